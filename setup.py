"""What pyproject.toml cannot say: the design files live in ``models/``, where a new design
starts, and ship inside the package as ``ftrac_design.presets`` (the build maps the folder in;
an editable install finds it there too)."""

from setuptools import find_packages, setup

setup(
    packages=[*find_packages(include=["ftrac_design*"]), "ftrac_design.presets"],
    package_dir={"ftrac_design.presets": "models"},
)
