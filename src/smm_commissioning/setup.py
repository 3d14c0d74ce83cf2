"""Packaging of smm_commissioning (ament_python: colcon build and pip install -e both work)."""

import sys
from pathlib import Path

from setuptools import find_packages, setup

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # src/user_commands.py
from user_commands import command_classes

PACKAGE = "smm_commissioning"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test", "tests"]),
    package_data={PACKAGE: ["py.typed"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
    ],
    install_requires=["setuptools", "numpy", "python-can"],
    zip_safe=True,
    maintainer="SMM control stack maintainers",
    maintainer_email="smm-maintainers@example.org",
    description="Guided commissioning of the bench: probe, jog, identify, tune, verify (smm-commission).",
    license="Apache-2.0",
    cmdclass=command_classes("smm-commission"),  # user-facing: also in <prefix>/bin
    entry_points={
        "console_scripts": ["smm-commission = smm_commissioning.cli:main"],
    },
)
