"""m-explore's launch, as its users write it: the map_merge executable of the multirobot_map_merge
package with a params file (default: this package's config/params.yaml)."""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description():
    config = os.path.join(get_package_share_directory("multirobot_map_merge"), "config", "params.yaml")
    return LaunchDescription([
        DeclareLaunchArgument("params_file", default_value=config),
        Node(package="multirobot_map_merge", executable="map_merge", name="map_merge",
             parameters=[LaunchConfiguration("params_file")], output="screen"),
    ])
