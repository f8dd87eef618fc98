"""Package discovery only; everything else is in pyproject.toml.

Every subpackage of usdgaze/ is found on its own, and the schema files at the top-level schemas/ folder
ship as ``usdgaze.schemas``.
"""

from setuptools import find_packages, setup

setup(
    packages=find_packages(include=["usdgaze", "usdgaze.*"]) + ["usdgaze.schemas"],
    package_dir={"usdgaze.schemas": "schemas"},
)
