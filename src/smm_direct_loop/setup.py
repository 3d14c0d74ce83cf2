"""Packaging of smm_direct_loop (ament_python: colcon build and pip install -e both work)."""

from setuptools import find_packages, setup

PACKAGE = "smm_direct_loop"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test", "tests"]),
    package_data={PACKAGE: ["py.typed"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="SMM control stack maintainers",
    maintainer_email="smm-maintainers@example.org",
    description="The bench's direct loop: the bridge's I/O and the control chain in one thread.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": ["direct_loop = smm_direct_loop.host:main"],
    },
)
