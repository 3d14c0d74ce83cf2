"""Packaging of smm_analysis (ament_python: colcon build and pip install -e both work)."""

import sys
from glob import glob
from pathlib import Path

from setuptools import find_packages, setup

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # src/user_commands.py
from user_commands import command_classes

PACKAGE = "smm_analysis"

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
    install_requires=[
        "setuptools",
        "numpy",
        "PyYAML",
        "matplotlib",
        "scipy",
        "rosbags",
        "pyarrow",
        "distributed",
    ],
    zip_safe=True,
    maintainer="SMM control stack maintainers",
    maintainer_email="smm-maintainers@example.org",
    description="Offline closed loop, paper reproduction, metrics, and analysis and re-run of recorded bags.",
    license="Apache-2.0",
    cmdclass=command_classes("smm-reproduce", "smm-sweep"),  # user-facing: also in <prefix>/bin
    entry_points={
        "console_scripts": [
            "smm-reproduce = smm_analysis.reproduction.cli:main",
            "smm-sweep = smm_analysis.sweep.cli:main",
        ],
        "smm_bag.commands": [
            "analyze = smm_analysis.runs.cli:add_analyze",
            "rerun = smm_analysis.runs.cli:add_rerun",
            "identify = smm_analysis.identify_command:add_identify",
        ],
    },
)
