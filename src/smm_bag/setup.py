"""Packaging of smm_bag (ament_python: colcon build and pip install -e both work)."""

import sys
from glob import glob
from pathlib import Path

from setuptools import find_packages, setup

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # src/user_commands.py
from user_commands import command_classes

PACKAGE = "smm_bag"

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
        "mcap",
        "rosbags",
        "zstandard",
        "lz4",
    ],
    zip_safe=True,
    maintainer="SMM control stack maintainers",
    maintainer_email="smm-maintainers@example.org",
    description="MCAP rosbag2 bags of SMM runs: writer, reader, repair, info, recorder node and replay.",
    license="Apache-2.0",
    cmdclass=command_classes("smm-bag"),  # user-facing: also in <prefix>/bin
    entry_points={
        "console_scripts": [
            "smm-bag = smm_bag.cli:main",
            "recorder_node = smm_bag.recorder_node:main",
        ],
    },
)
