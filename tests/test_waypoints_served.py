"""The waypoints file's troubles as a user of the HTTP API meets them (issue 10, items 8-10).

A real Robot on the test ROS master under waitress on port 0; a second real
process holds the file lock.
"""

import concurrent.futures
import subprocess
import sys

import requests

from tests.conftest import wait_for
from tests.test_client import robot_server
from tests.test_waypoints import SEED_WRITTEN
from tests.test_waypoints_file import ALIAS_BOMB, LOCK_HOLDER


def test_a_stuck_lock_holder_gets_a_503_naming_the_lock_while_reads_and_goto_answer(ros_node, unique_name, tmp_path):
    path = tmp_path / "waypoints.yaml"
    path.write_text(SEED_WRITTEN)
    holder = subprocess.Popen([sys.executable, "-c", LOCK_HOLDER, str(path) + ".lock"],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with robot_server(ros_node, unique_name, path) as live, \
                concurrent.futures.ThreadPoolExecutor(1) as pool:
            wait_for(live.robot.navigator.server_ready, timeout=15, message="the action client to see move_base")
            put = pool.submit(requests.put, live.url + "/waypoints/porch", json={"x": 1, "y": 2, "yaw": 0},
                              timeout=60)
            wait_for(lambda: ("PUT", "/waypoints/porch", {"x": 1, "y": 2, "yaw": 0}) in live.calls)
            assert len(requests.get(live.url + "/waypoints", timeout=10).json()["waypoints"]) == 3
            assert requests.get(live.url + "/waypoints/office", timeout=10).json()["yaw"] == -1.57
            assert requests.post(live.url + "/goto", json={"name": "kitchen"}, timeout=10).status_code == 202
            assert requests.get(live.url + "/health", timeout=10).status_code == 200
            assert not put.done(), "the PUT should still be waiting for the lock (3 s)"
            answer = put.result(timeout=60)
        assert answer.status_code == 503
        body = answer.json()
        assert body["status"] == "error" and body["error"] == "waypoints_locked"
        assert str(path) + ".lock" in body["message"]
        assert path.read_text() == SEED_WRITTEN
    finally:
        holder.kill()
        holder.communicate()


def test_an_emptied_file_answers_409_and_an_alias_bomb_keeps_status_small(ros_node, unique_name, tmp_path):
    path = tmp_path / "waypoints.yaml"
    path.write_text(SEED_WRITTEN)
    with robot_server(ros_node, unique_name, path, move_base=False) as live:
        path.write_text("")  # a failed printf > file
        assert len(requests.get(live.url + "/waypoints", timeout=10).json()["waypoints"]) == 3
        answer = requests.put(live.url + "/waypoints/porch", json={"x": 1, "y": 2, "yaw": 0}, timeout=10)
        assert answer.status_code == 409
        body = answer.json()
        assert body["error"] == "waypoints_file" and "is empty" in body["message"]
        # no .bak yet (asserted below): no `cp FILE.bak FILE` that would fail
        assert ".bak" not in body["message"] and "waypoints: {}" in body["message"]
        assert requests.delete(live.url + "/waypoints/kitchen", timeout=10).status_code == 409
        assert path.read_text() == "" and not (tmp_path / "waypoints.yaml.bak").exists()

        path.write_text(ALIAS_BOMB)
        status = requests.get(live.url + "/status", timeout=10)
        assert len(status.content) < 5000
        assert "anchors and aliases" in status.json()["waypoints"]["problem"]


def test_puts_stuck_on_the_lock_free_every_worker_thread_again(ros_node, unique_name, tmp_path):
    path = tmp_path / "waypoints.yaml"
    path.write_text(SEED_WRITTEN)
    holder = subprocess.Popen([sys.executable, "-c", LOCK_HOLDER, str(path) + ".lock"],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with robot_server(ros_node, unique_name, path, move_base=False) as live, \
                concurrent.futures.ThreadPoolExecutor(4) as pool:
            puts = [pool.submit(requests.put, live.url + "/waypoints/p{}".format(i),
                                json={"x": i, "y": 0, "yaw": 0}, timeout=60) for i in range(4)]
            wait_for(lambda: sum(c[0] == "PUT" for c in live.calls) == 4)  # every worker thread is taken
            assert requests.get(live.url + "/health", timeout=30).status_code == 200
            assert requests.post(live.url + "/stop", timeout=30).status_code == 200
            assert [p.result(timeout=60).status_code for p in puts] == [503] * 4
    finally:
        holder.kill()
        holder.communicate()
