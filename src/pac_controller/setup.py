import os
from glob import glob

from setuptools import setup

package_name = "pac_controller"

setup(
    name=package_name,
    version="0.1.0",
    packages=[package_name],
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        # config/<node>.yaml: generated from the parameter declarations (python -m pac_rig.configs --write).
        (os.path.join("share", package_name, "config"), glob("config/*.yaml")),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="PAC maintainers",
    maintainer_email="pac@example.com",
    description=(
        "Force controller: reference, control laws (backstepping, PID, LQR, passive) and controller_node."
    ),
    license="Apache-2.0",
    tests_require=["pytest"],
    entry_points={
        "console_scripts": [
            "controller_node = pac_controller.controller_node:main",
            "controller_relay = pac_controller.relay:main",
        ],
    },
)
