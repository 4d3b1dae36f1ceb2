"""record-waypoints saving: through a live server, or to the file beside one, and Ctrl-C."""

import contextlib
import os
import queue
import signal
import subprocess
import sys
import threading

import requests
import rospy
import yaml
from geometry_msgs.msg import PointStamped

from flask_move_server.core.geometry import Pose2D
from flask_move_server.recorder.savers import FileSaver, ServerSaver, choose_saver
from flask_move_server.robotctl.api import ExitStatus
from flask_move_server.waypoints.yaml_format import parse
from tests.conftest import ROOT, default_sigint, free_port, stop_process, wait_for
from tests.test_client import robot_server
from tests.test_recorder import Rig

SEED = "waypoints:\n  kitchen: [1.0, 2.0, 0.5]\n"


def test_with_a_server_answering_waypoints_go_through_its_api(ros_node, unique_name, tmp_path):
    served = tmp_path / "served.yaml"
    served.write_text(SEED)
    with robot_server(ros_node, unique_name, served, move_base=False) as live:
        said = []
        saver = choose_saver(str(tmp_path / "unused.yaml"), live.url, say=said.append)
        assert isinstance(saver, ServerSaver) and said == []
        rig = Rig(unique_name + "r", tmp_path / "unused.yaml", auto_names=True, saver=saver)
        try:
            rig.click(5.0, 6.0)
            rig.session.handle_line("rename wp1 desk")
            rig.session.handle_line("delete kitchen")
            rig.session.handle_line("undo")
        finally:
            rig.close()
        listed = requests.get(live.url + "/waypoints", timeout=10).json()["waypoints"]
        assert [(w["name"], w["x"], w["y"]) for w in listed] == [("desk", 5.0, 6.0), ("kitchen", 1.0, 2.0)]
        assert ("PUT", "/waypoints/wp1", {"x": 5.0, "y": 6.0, "yaw": 0.0}) in live.calls
    assert list(parse(served.read_text())) == ["desk", "kitchen"]
    assert not (tmp_path / "unused.yaml").exists()


def test_no_server_answering_falls_back_to_the_file(tmp_path):
    said = []
    url = "http://127.0.0.1:{}".format(free_port())
    saver = choose_saver(str(tmp_path / "w.yaml"), url, say=said.append)
    assert isinstance(saver, FileSaver)
    assert said == ["The server at {} does not answer; saving to {} directly.".format(url, tmp_path / "w.yaml")]


def test_a_server_refusing_the_token_is_an_error_not_a_fallback(ros_node, unique_name, tmp_path):
    with robot_server(ros_node, unique_name, tmp_path / "w.yaml", token="s3cret", move_base=False) as live:
        try:
            choose_saver(str(tmp_path / "w.yaml"), live.url, token="wrong")
        except Exception as exc:
            assert getattr(exc, "exit_status", None) == ExitStatus.UNAUTHORIZED
        else:
            raise AssertionError("a refused token must not fall back to writing the file")


def test_the_file_path_beside_a_writing_server_loses_no_update(ros_node, unique_name, tmp_path):
    shared = tmp_path / "shared.yaml"
    shared.write_text(SEED)
    with robot_server(ros_node, unique_name, shared, move_base=False) as live:
        saver = FileSaver(str(shared))  # the recorder's own store on the same file, as another process has
        errors = []

        def server_writes():
            with requests.Session() as http:
                for i in range(25):
                    r = http.put("{}/waypoints/api{}".format(live.url, i), json={"x": i, "y": 0, "yaw": 0}, timeout=30)
                    if r.status_code != 201:
                        errors.append(r.text)

        writer = threading.Thread(target=server_writes)
        writer.start()
        rig = Rig(unique_name + "r", shared, saver=saver)
        try:
            for i in range(25):
                rig.session.save("rec{}".format(i), Pose2D(0.0, float(i), 0.0), "test")
        finally:
            writer.join()
            rig.close()
        assert errors == []
        names = set(parse(shared.read_text()))
        assert names == {"kitchen"} | {"api{}".format(i) for i in range(25)} | {"rec{}".format(i) for i in range(25)}
        assert {w["name"] for w in requests.get(live.url + "/waypoints", timeout=10).json()["waypoints"]} == names


# the whole process ---------------------------------------------------------------------


@contextlib.contextmanager
def recorder_process(*args):
    proc = subprocess.Popen([sys.executable, "-m", "flask_move_server.recorder", *args],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            cwd=ROOT, text=True, env=dict(os.environ, PYTHONUNBUFFERED="1"), preexec_fn=default_sigint)
    lines = queue.Queue()
    lines.transcript = []  # every line, for checks after the process ends

    def read():
        for line in proc.stdout:
            lines.transcript.append(line.rstrip("\n"))
            lines.put(line.rstrip("\n"))

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        yield proc, lines
        reader.join(10)
    finally:
        stop_process(proc)
        proc.stdin.close()
        proc.stderr.close()


def _next_line(lines, predicate, what, timeout=30):
    seen = []

    def match():
        with contextlib.suppress(queue.Empty):
            while True:
                line = lines.get_nowait()
                seen.append(line)
                if predicate(line):
                    return line
        return None

    try:
        return wait_for(match, timeout=timeout, message=what)
    except AssertionError:
        raise AssertionError("{}; the recorder said last: {}".format(what, seen[-5:]))


def test_ctrl_c_while_saving_leaves_the_file_valid_and_complete(ros_node, unique_name, tmp_path):
    big = tmp_path / "big.yaml"  # a big file makes every save take a while (long names: a map keeps 1000)
    old = 900
    big.write_text("waypoints:\n" + "".join("  old{}_{}: [{}.5, 1.0, 0.0]\n".format(i, "x" * 50, i)
                                            for i in range(old)))
    topic = "/{}/clicked_point".format(unique_name)
    with recorder_process("--waypoints", str(big), "--auto-names", "--clicked-topic", topic,
                          "--map-frame", unique_name + "_map") as (proc, lines):
        _next_line(lines, lambda line: line.startswith("Recording waypoints in the file"), "the recorder to start")
        _next_line(lines, lambda line: "No '{}_map' frame in tf yet".format(unique_name) in line,
                   "the missing map frame explained")
        pub = rospy.Publisher(topic, PointStamped, queue_size=100)
        wait_for(lambda: pub.get_num_connections() > 0, message="the recorder subscribing")
        stop = threading.Event()

        def click_fast():
            msg = PointStamped()
            msg.header.frame_id = unique_name + "_map"
            while not stop.is_set():
                pub.publish(msg)
                stop.wait(0.01)

        clicker = threading.Thread(target=click_fast)
        clicker.start()
        try:
            for _ in range(3):
                _next_line(lines, lambda line: line.startswith("Saved wp"), "a save")
            proc.send_signal(signal.SIGINT)
            _next_line(lines, lambda line: line.startswith("Bye"), "the recorder to stop on Ctrl-C")
            assert proc.wait(30) == 0
        finally:
            stop.set()
            clicker.join()
            pub.unregister()
    saved = [line.split()[1] for line in lines.transcript if line.startswith("Saved wp")]
    bye = [line for line in lines.transcript if line.startswith("Bye")]
    waypoints = parse(big.read_text())  # valid: parses, no partial entry
    assert set(saved) <= set(waypoints) and len(waypoints) == old + len(saved)
    assert bye == ["Bye: {} waypoints in the file {}.".format(len(waypoints), big)]
    assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")] == []


def test_typed_commands_and_quit(ros_master, tmp_path):
    path = tmp_path / "w.yaml"
    path.write_text(SEED)
    with recorder_process("--waypoints", str(path)) as (proc, lines):
        out, err = proc.communicate('rename kitchen "kitchen table"\nlist\nquit\n', timeout=60)
        assert proc.returncode == 0, err
    assert list(yaml.safe_load(path.read_text())["waypoints"]) == ["kitchen table"]


def test_no_ros_master_says_what_to_do(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "flask_move_server.recorder", "--waypoints", str(tmp_path / "w")],
                          env=dict(os.environ, ROS_MASTER_URI="http://127.0.0.1:{}".format(free_port())),
                          cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert proc.returncode == ExitStatus.UNREACHABLE
    assert proc.stderr.startswith("record-waypoints: no ROS master answers at http://127.0.0.1:")
    assert "start roscore" in proc.stderr and "Traceback" not in proc.stderr


def test_a_ctrl_c_during_a_save_takes_effect_right_after_it(tmp_path, sigint_at_default):
    from flask_move_server.recorder.prompt import interrupts_deferred
    from flask_move_server.waypoints import make_waypoint

    saver = FileSaver(str(tmp_path / "w.yaml"))
    done = []
    try:
        with interrupts_deferred():
            os.kill(os.getpid(), signal.SIGINT)  # as if Ctrl-C landed mid-save
            saver.put(make_waypoint("kitchen", 1, 2, 3))
            done.append("reported")
    except KeyboardInterrupt:
        done.append("interrupted")
    assert done == ["reported", "interrupted"]
    assert list(parse((tmp_path / "w.yaml").read_text())) == ["kitchen"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_auto_names_without_a_terminal_records_until_sigterm(ros_node, unique_name, tmp_path):
    """roslaunch starts record-waypoints with its input at end: with --auto-names that is no reason to quit."""
    target = tmp_path / "waypoints.yaml"
    topic = "/{}/clicked_point".format(unique_name)
    with recorder_process("--waypoints", str(target), "--auto-names", "--clicked-topic", topic,
                          "--map-frame", unique_name + "_map") as (proc, lines):
        proc.stdin.close()  # end of input at once, as under roslaunch
        _next_line(lines, lambda line: line.startswith("Recording waypoints in the file"), "the recorder to start")
        pub = rospy.Publisher(topic, PointStamped, queue_size=10)
        try:
            wait_for(lambda: pub.get_num_connections() > 0, message="the recorder subscribing")
            assert proc.poll() is None, "the recorder quit at the end of its input"
            msg = PointStamped()
            msg.header.frame_id = unique_name + "_map"
            msg.point.x = 1.5
            pub.publish(msg)
            _next_line(lines, lambda line: line.startswith("Saved wp1"), "the click saved")
            proc.send_signal(signal.SIGTERM)
            _next_line(lines, lambda line: line.startswith("Bye"), "the recorder to stop on SIGTERM")
            assert proc.wait(30) == 0
        finally:
            pub.unregister()
    assert parse(target.read_text())["wp1"].x == 1.5
