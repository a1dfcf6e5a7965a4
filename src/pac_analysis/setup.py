from setuptools import setup

package_name = "pac_analysis"

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
        "Reads pac bags: contact-force metrics, loop timing, figures, report, info, recover, re-estimation."
    ),
    license="Apache-2.0",
    tests_require=["pytest"],
    entry_points={
        "console_scripts": [
            "report = pac_analysis.report:main",
            "info = pac_analysis.info:main",
            "recover = pac_analysis.recover:main",
            "re_estimate = pac_analysis.re_estimate:main",
        ],
    },
)
