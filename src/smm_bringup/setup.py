"""Packaging of smm_bringup (ament_python: colcon build and pip install -e both work)."""

import sys
from glob import glob
from pathlib import Path

from setuptools import find_packages, setup

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # src/user_commands.py
from user_commands import command_classes

PACKAGE = "smm_bringup"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test", "tests"]),
    package_data={PACKAGE: ["py.typed"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/launch", glob("launch/*.launch.py")),
        (f"share/{PACKAGE}/config", glob("config/*.yaml")),
    ],
    install_requires=["setuptools", "numpy"],
    zip_safe=True,
    maintainer="SMM control stack maintainers",
    maintainer_email="smm-maintainers@example.org",
    description="The whole SMM graph: its description, smm-launch, launch files, scenarios, the demo.",
    license="Apache-2.0",
    cmdclass=command_classes("smm-launch", "smm-demo"),  # user-facing: also in <prefix>/bin
    entry_points={
        "console_scripts": [
            "smm-launch = smm_bringup.launcher:main",
            "smm-demo = smm_bringup.demo:main",
        ],
    },
)
