from setuptools import setup

package_name = "pac_ros2cli"

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
    description=(
        "A stand-in for ros2cli (not installable from PyPI): the daily `ros2` verbs over rclpy's graph "
        "API and pac's tools; scripts/bin/ros2 calls it."
    ),
    license="Apache-2.0",
    tests_require=["pytest"],
    entry_points={"console_scripts": []},
)
