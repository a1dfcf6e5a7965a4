import os
from glob import glob

from setuptools import setup

package_name = "pac_rig"

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
        "Running the rig: node registry, recorder, launcher, offline closed loop, compiled batch, "
        "simulate, replay, live view."
    ),
    license="Apache-2.0",
    tests_require=["pytest"],
    entry_points={
        "console_scripts": [
            "recorder = pac_rig.recorder:main",
            "composed = pac_rig.composed:main",
            "simulate = pac_rig.simulate:main",
            "rig_params = pac_rig.rig_params:main",
            "replay = pac_rig.replay:main",
            "live_view = pac_rig.live_view:main",
        ],
    },
)
