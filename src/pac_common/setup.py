from setuptools import setup

package_name = "pac_common"

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
        "What every pac package shares: parameter declarations and validation, rclpy node glue, "
        "message fields, contact-force statistics (EN 50317/50318/50367), strict JSON and Markdown "
        "writers (no nodes)."
    ),
    license="Apache-2.0",
    tests_require=["pytest"],
    entry_points={
        "console_scripts": [],
    },
)
