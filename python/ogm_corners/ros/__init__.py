"""ROS 2 map merging: the ``map_merge`` node (``python -m ogm_corners.ros``, a drop-in for m-explore's
``multirobot_map_merge``) and its logic without ROS (``ogm_corners.ros.live``), which needs no ROS install."""
