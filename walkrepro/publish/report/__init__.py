"""A static HTML report of the reproduction: ``walkrepro report``.

Built from the committed references (``results/``) or from a ``walkrepro check`` output
directory, it reads JSON and copies files, never re-runs anything, and works from
``file://`` (relative links only, no scripts, no network):

- :mod:`~walkrepro.publish.report.sources` finds each experiment's verdict, figures and video;
- :mod:`~walkrepro.publish.report.claims` turns verdict rows into the paper's claims;
- :mod:`~walkrepro.publish.report.maps` evaluates the declared maps' claims on their cells;
- :mod:`~walkrepro.publish.report.robots` renders a robot's README (its sources);
- :mod:`~walkrepro.publish.report.html` holds the page pieces and the style sheet;
- :mod:`~walkrepro.publish.report.site` writes the index, one page per paper and the assets.
"""

from walkrepro.publish.report.site import ReportSite, build_report

__all__ = ["ReportSite", "build_report"]
