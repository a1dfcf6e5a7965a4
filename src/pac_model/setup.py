from setuptools import setup

package_name = "pac_model"

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
        "The paper's pantograph-catenary model (eqs. 2-15) and its parameter sets: no ROS, no simulation."
    ),
    license="Apache-2.0",
    tests_require=["pytest"],
)
