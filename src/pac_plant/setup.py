import os
from glob import glob

from setuptools import setup

package_name = "pac_plant"

setup(
    name=package_name,
    version="0.1.0",
    packages=[package_name, package_name + ".catenary", package_name + ".hardware"],
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
        "Simulated plant: the lumped model or the finite-element catenary, plant_node "
        "(measurements, ground truth, commands applied)."
    ),
    license="Apache-2.0",
    tests_require=["pytest"],
    entry_points={
        "console_scripts": [
            "plant_node = pac_plant.plant_node:main",
            "plant_relay = pac_plant.relay:main",
        ],
    },
)
