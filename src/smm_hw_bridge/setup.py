"""Packaging of smm_hw_bridge (ament_python: colcon build and pip install -e both work)."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = "smm_hw_bridge"

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
    install_requires=["setuptools", "numpy", "pyserial", "canopen", "python-can"],
    zip_safe=True,
    maintainer="SMM control stack maintainers",
    maintainer_email="smm-maintainers@example.org",
    description="Bridge between the SMM ROS interfaces and the hydraulic test bench.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": ["hw_bridge_node = smm_hw_bridge.bridge_node:main"],
    },
)
