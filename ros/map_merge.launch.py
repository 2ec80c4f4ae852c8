"""ROS 2 launch file for the map_merge node of ogm-corners, in place of m-explore's multirobot_map_merge.

    ros2 launch ./map_merge.launch.py                      # multirobot_map_merge/config/params.yaml
    ros2 launch ./map_merge.launch.py params:=/path/to/your/multirobot_map_merge_params.yaml

The node is a Python module, not a ROS package: it runs as a process of the Python that has both rclpy and
ogm_corners (`pip install ogm-corners` into the Python your sourced ROS 2 uses). An existing launch file
that starts `Node(package="multirobot_map_merge", executable="map_merge", ...)` changes that one action to
the ExecuteProcess below; its params file loads unchanged.
"""

import os

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, ExecuteProcess
from launch.substitutions import LaunchConfiguration


def generate_launch_description():
    here = os.path.dirname(os.path.abspath(__file__))
    return LaunchDescription([
        DeclareLaunchArgument("params", default_value=os.path.join(here, "multirobot_map_merge", "config", "params.yaml")),
        DeclareLaunchArgument("python", default_value="python3"),
        ExecuteProcess(
            cmd=[LaunchConfiguration("python"), "-m", "ogm_corners.ros", "--ros-args",
                 "--params-file", LaunchConfiguration("params")],
            output="screen",
        ),
    ])
