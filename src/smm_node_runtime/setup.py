"""Packaging of smm_node_runtime (ament_python: colcon build and pip install -e both work)."""

from setuptools import find_packages, setup

PACKAGE = "smm_node_runtime"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test", "tests"]),
    package_data={PACKAGE: ["py.typed", "known_parameters.json"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
    ],
    install_requires=["setuptools", "numpy", "pyyaml"],
    zip_safe=True,
    maintainer="SMM control stack maintainers",
    maintainer_email="smm-maintainers@example.org",
    description="Runtime of every SMM node: main, executor, base classes, parameters, diagnostics.",
    license="Apache-2.0",
)
