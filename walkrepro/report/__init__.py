"""A static HTML report of the reproduction: ``walkrepro report``.

Built from the committed references (``results/``) or from a ``walkrepro check`` output
directory, it reads JSON and copies files, never re-runs anything, and works from
``file://`` (relative links only, no scripts, no network):

- :mod:`~walkrepro.report.sources` finds each experiment's verdict, figures and video;
- :mod:`~walkrepro.report.claims` turns verdict rows into the paper's claims;
- :mod:`~walkrepro.report.maps` evaluates the declared maps' claims on their cells;
- :mod:`~walkrepro.report.robots` renders a robot's README (its sources);
- :mod:`~walkrepro.report.html` holds the page pieces and the style sheet;
- :mod:`~walkrepro.report.site` writes the index, one page per paper and the assets.
"""

from walkrepro.report.site import ReportSite, build_report

__all__ = ["ReportSite", "build_report"]
