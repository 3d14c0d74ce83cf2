"""Packaging of smm_controller (ament_python: colcon build and pip install -e both work)."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = "smm_controller"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test", "tests"]),
    package_data={PACKAGE: ["py.typed"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", glob("config/*.yaml")),
    ],
    install_requires=["setuptools", "numpy"],
    zip_safe=True,
    maintainer="SMM control stack maintainers",
    maintainer_email="smm-maintainers@example.org",
    description="FPDESO controller of the SMM: TD, fuzzy PD, FLESO, robust term, baselines, and their nodes.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "reference_node = smm_controller.reference_node:main",
            "td_node = smm_controller.td_node:main",
            "fleso_node = smm_controller.fleso_node:main",
            "controller_node = smm_controller.controller_node:main",
        ],
    },
)
