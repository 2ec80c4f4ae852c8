"""The ament_python package `multirobot_map_merge`: the executable `map_merge` runs ogm-corners' node
(``ogm_corners.ros.node:main``), so `Node(package="multirobot_map_merge", executable="map_merge")` in an
existing launch file starts it. Build it in a colcon workspace in place of m-explore's package of the
same name (the two cannot be installed side by side)."""

from setuptools import setup

setup(
    name="multirobot_map_merge",
    version="0.1.0",
    packages=[],
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/multirobot_map_merge"]),
        ("share/multirobot_map_merge", ["package.xml"]),
        ("share/multirobot_map_merge/launch", ["launch/map_merge.launch.py"]),
        ("share/multirobot_map_merge/config", ["config/params.yaml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    entry_points={"console_scripts": ["map_merge = ogm_corners.ros.node:main"]},
)
