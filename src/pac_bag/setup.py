from setuptools import setup

package_name = "pac_bag"

setup(
    name=package_name,
    version="0.1.0",
    packages=[package_name],
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="PAC maintainers",
    maintainer_email="pac@example.com",
    description="Bag I/O of pac runs: rosbag2 (MCAP) writing, reading and recovery, CDR in bulk.",
    license="Apache-2.0",
    tests_require=["pytest"],
    entry_points={"console_scripts": []},
)
