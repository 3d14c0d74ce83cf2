"""Packaging of smm_bench_emulator (ament_python: colcon build and pip install -e both work)."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = "smm_bench_emulator"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test", "tests"]),
    package_data={PACKAGE: ["py.typed", "eds/*.eds"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/launch", glob("launch/*.launch.py")),
        (f"share/{PACKAGE}/config", glob("config/*.yaml")),
    ],
    install_requires=["setuptools", "numpy", "PyYAML", "canopen", "python-can"],
    zip_safe=True,
    maintainer="SMM control stack maintainers",
    maintainer_email="smm-maintainers@example.org",
    description="The bench in a box: the I/O board side of the SMM hardware protocol over loopback UDP.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": ["smm_bench_emulator = smm_bench_emulator.cli:main"],
    },
)
