from setuptools import find_packages, setup

package_name = "pac_experiments"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(include=[package_name, package_name + ".*"]),
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
            "bench = pac_experiments.bench.rig:main",
            "soak = pac_experiments.bench.soak:main",
            "sweep = pac_experiments.sweep:main",
            "reproduce = pac_experiments.reproduce:main",
            "campaign = pac_experiments.campaign.cli:main",
            "campaign_bench = pac_experiments.bench.campaign:main",
            "catenary = pac_experiments.catenary.line:main",
            "fe_experiment = pac_experiments.catenary.experiment:main",
            "campaign_summary = pac_experiments.campaign.summary:main",
            "realistic_figure = pac_experiments.realistic.figure:main",
            "fe_live = pac_experiments.catenary.live:main",
            "two_pantographs = pac_experiments.catenary.two_pantographs:main",
            "realistic_goals = pac_experiments.realistic.goals:main",
            "realistic_pair = pac_experiments.realistic.pair:main",
            "realistic_pair_bound = pac_experiments.realistic.pair_bound:main",
            "realistic_pair_draw = pac_experiments.realistic.pair_draw:main",
            "realistic_passes = pac_experiments.realistic.passes:main",
            "realistic_laws_figures = pac_experiments.realistic.laws_figures:main",
            "realistic_overlap_figure = pac_experiments.realistic.overlap_figure:main",
            "line_response = pac_experiments.catenary.line_response:main",
        ],
    },
)
