"""Packaging of smm_bringup (ament_python: colcon build and pip install -e both work)."""

from glob import glob

from setuptools import find_packages, setup

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
    install_requires=["setuptools", "numpy", "pyyaml"],
    zip_safe=True,
    maintainer="SMM control stack maintainers",
    maintainer_email="smm-maintainers@example.org",
    description="The whole SMM graph: its description, smm-launch, launch files, scenarios, the demo.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "smm-launch = smm_bringup.launcher:main",
            "smm-demo = smm_bringup.demo:main",
            "smm-sweep = smm_bringup.sweep.cli:main",
        ],
    },
)
