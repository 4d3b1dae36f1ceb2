"""A map named in the owner's language reaches map_server whole on the robot (issue 22, item 6).

The mode manager starts ``roslaunch navigation.launch map:=<maps folder>/NAME.yaml``; roslaunch
splits a node's ``args`` with shlex, so the map's path must be quoted in the launch file: a space
("living room") split it in two, an apostrophe ("Mum's room") was an unclosed quote. roslaunch's
own parse and its own argument builder, in this process, against the stub packages.
"""

import pytest
import roslaunch.core
import roslaunch.node_args

from tests.test_launch import launch_config


@pytest.mark.parametrize("name", ["living room", "Mum's room", "Mum\u2019s room", "Küche", "台所"])
def test_the_map_path_reaches_map_server_as_one_argument(name, monkeypatch, tmp_path):
    path = str(tmp_path / "maps" / (name + ".yaml"))
    config = launch_config("navigation.launch", ["map:=" + path], monkeypatch)
    (node,) = [n for n in config.nodes if n.name == "map_server"]
    argv = roslaunch.node_args.create_local_process_args(node, roslaunch.core.local_machine())
    assert [arg for arg in argv[1:] if not arg.startswith("__name:=")] == [path], argv
