"""The files a ROS 2 user takes: the ament_python package `multirobot_map_merge` (m-explore's package and
executable names, so an existing launch file starts this node unchanged), the launch files and the params
file in multirobot_map_merge's layout. No colcon here: checked as files (the package's metadata, its entry
point, the files it installs, the launch files compile, the params are the node's)."""

import ast
import os
import xml.etree.ElementTree as ET

import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
PKG = os.path.join(ROOT, "ros", "multirobot_map_merge")
NODE = os.path.join(ROOT, "python", "ogm_corners", "ros", "node.py")


def setup_call():
    tree = ast.parse(open(os.path.join(PKG, "setup.py")).read())
    call = next(n for n in ast.walk(tree) if isinstance(n, ast.Call) and getattr(n.func, "id", "") == "setup")
    return {k.arg: k.value for k in call.keywords}


def node_dict(name):
    tree = ast.parse(open(NODE).read())
    for n in tree.body:
        target = getattr(n, "target", None) or (n.targets[0] if isinstance(n, ast.Assign) else None)
        if getattr(target, "id", None) == name:
            return eval(compile(ast.Expression(n.value), NODE, "eval"), {})  # literals and `1 << 27`
    raise AssertionError(f"{name} not in node.py")


def test_the_package_is_an_ament_python_package_named_as_m_explores():
    root = ET.parse(os.path.join(PKG, "package.xml")).getroot()
    assert root.get("format") == "3" and root.findtext("name") == "multirobot_map_merge"
    assert root.find("export/build_type").text == "ament_python"
    assert os.path.isfile(os.path.join(PKG, "resource", "multirobot_map_merge"))
    kw = setup_call()
    assert ast.literal_eval(kw["name"]) == "multirobot_map_merge"
    scripts = ast.literal_eval(kw["entry_points"])["console_scripts"]
    assert scripts == ["map_merge = ogm_corners.ros.node:main"]
    assert "def main(" in open(NODE).read()
    # Every file it installs is there.
    for entry in kw["data_files"].elts:
        for path in ast.literal_eval(entry.elts[1]):
            assert os.path.isfile(os.path.join(PKG, path)), path
    cfg = open(os.path.join(PKG, "setup.cfg")).read()
    assert "install_scripts=$base/lib/multirobot_map_merge" in cfg  # where ros2 run / launch look


def test_the_package_is_licensed_as_the_project_with_both_licence_texts_present():
    root = ET.parse(os.path.join(PKG, "package.xml")).getroot()
    assert sorted(e.text for e in root.findall("license")) == ["Apache-2.0", "MIT"]
    cargo = open(os.path.join(ROOT, "Cargo.toml")).read()
    assert 'license = "MIT OR Apache-2.0"' in cargo
    mit = open(os.path.join(ROOT, "LICENSE-MIT")).read()
    apache = open(os.path.join(ROOT, "LICENSE-APACHE")).read()
    assert mit.startswith("Copyright (c)") and "Permission is hereby granted, free of charge" in mit
    assert "Apache License" in apache and "Version 2.0, January 2004" in apache
    assert "END OF TERMS AND CONDITIONS" in apache


def test_the_launch_files_compile_and_start_the_node():
    for path in (os.path.join(PKG, "launch", "map_merge.launch.py"),
                 os.path.join(ROOT, "ros", "map_merge.launch.py")):
        text = open(path).read()
        compile(text, path, "exec")
        assert "generate_launch_description" in text
    assert 'Node(package="multirobot_map_merge", executable="map_merge"' in open(
        os.path.join(PKG, "launch", "map_merge.launch.py")).read()


def test_the_params_file_holds_every_multirobot_map_merge_parameter_with_its_default():
    params = yaml.safe_load(open(os.path.join(PKG, "config", "params.yaml")))["map_merge"]["ros__parameters"]
    theirs, ours = node_dict("THEIRS"), node_dict("OURS")
    for k, v in theirs.items():
        assert k in params, k
        if k != "known_init_poses":  # false in the example: the node finds the poses
            assert params[k] == v, (k, params[k], v)
    assert params["known_init_poses"] is False
    for k, v in params.items():
        assert k in theirs or k in ours, k  # no parameter the node does not know
