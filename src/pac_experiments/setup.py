from setuptools import setup

package_name = "pac_experiments"

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
        "Studies that run and analyse the rig: demo, bench, sweep, reproduce, campaigns, the FE "
        "catenary experiment, soak."
    ),
    license="Apache-2.0",
    tests_require=["pytest"],
    entry_points={
        "console_scripts": [
            "demo = pac_experiments.demo:main",
            "bench = pac_experiments.bench:main",
            "soak = pac_experiments.soak:main",
            "sweep = pac_experiments.sweep:main",
            "reproduce = pac_experiments.reproduce:main",
            "campaign = pac_experiments.campaign:main",
            "campaign_bench = pac_experiments.campaign_bench:main",
            "catenary = pac_experiments.fe_line:main",
            "fe_experiment = pac_experiments.fe_experiment:main",
            "campaign_summary = pac_experiments.campaign_summary:main",
            "realistic_figure = pac_experiments.realistic_figure:main",
            "fe_live = pac_experiments.fe_live:main",
            "two_pantographs = pac_experiments.two_pantographs:main",
            "realistic_pair = pac_experiments.realistic_pair:main",
            "realistic_passes = pac_experiments.realistic_passes:main",
            "realistic_laws_figures = pac_experiments.realistic_laws_figures:main",
            "line_response = pac_experiments.line_response:main",
        ],
    },
)
