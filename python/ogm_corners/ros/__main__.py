"""``python -m ogm_corners.ros``: the map_merge node (``ogm_corners.ros.node``)."""

import sys


def run() -> int:
    try:
        return _run()
    except KeyboardInterrupt:
        return 0  # Ctrl-C while the node is still loading: a clean stop, as it is once running


def _run() -> int:
    try:
        from .node import main
    except ImportError as e:
        print(
            f"ogm_corners.ros: ROS 2 is not importable here ({e}); source a ROS 2 install or "
            "pip install 'ogm-corners[ros]'",
            file=sys.stderr,
        )
        return 2
    return main(sys.argv)


if __name__ == "__main__":
    sys.exit(run())
