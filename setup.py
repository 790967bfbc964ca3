"""Packages for setuptools; everything else about the project is in pyproject.toml.

An installed walkrepro carries the repository's robots, experiment specs (with their
calibration files) and committed references (each experiment's metrics, verdict and run
record; each map's grid and cells) as ``walkrepro/_shipped/``, so that it runs without a
clone (walkrepro/locations.py). A checkout reads the same folders in place.
"""

from setuptools import find_packages, setup

#: Package name inside the wheel -> the repository folder it is built from.
SHIPPED = {
    "walkrepro._shipped.robots": "robots",
    "walkrepro._shipped.experiments": "experiments",
    "walkrepro._shipped.references": "results",
}

setup(
    packages=find_packages(include=["walkrepro*"]) + list(SHIPPED),
    package_dir=SHIPPED,
    package_data={
        "walkrepro._shipped.robots": ["*/robot.xml", "*/README.md"],
        "walkrepro._shipped.experiments": ["*.yaml", "calibration/*.yaml", "claims/*.yaml"],
        "walkrepro._shipped.references": [
            "*/metrics.json",
            "*/check.json",
            "*/run.json",
            "maps/*/sweep.yaml",
            "maps/*/cells.csv",
        ],
    },
)
