"""The explorer's rules, over stand-ins for the facade, the mode manager and the map service.

The frontier search is the real one (``explore/frontiers.py``) on small grids; what move_base
does with each goal is scripted here, so each rule can be driven to its edge: a goal move_base
aborts is given up (blacklisted) and the next frontier is tried; a goal the explorer replaced
itself is not; a stop that comes while a goal is being sent cancels that goal too; a mode switch
by someone else ends it; a taken name, the e-stop and a run under way are refused before
anything moves. The sim tests (test_explore_sim.py) drive the same code through the real stack.
"""

import threading
import time

import pytest

from flask_move_server.core.errors import EStopLatched, ExploreConflict, MapExists, NoPose
from flask_move_server.core.geometry import Pose2D
from flask_move_server.explore.explorer import Explorer
from flask_move_server.maps.mapfile import Grid
from flask_move_server.zones import make_zone
from tests.conftest import wait_for

RES = 0.1


def grid(rows):
    """A Grid from text rows, top row first: '#' occupied, '.' free, '?' unknown."""
    values = {"#": 100, ".": 0, "?": -1}
    height, width = len(rows), len(rows[0])
    cells = bytearray()
    for row in reversed(rows):
        cells += bytes(values[c] & 0xFF for c in row)
    return Grid(width, height, RES, 0.0, 0.0, bytes(cells))


# A room 2 m x 1 m known; unknown beyond its open left and right ends (two frontiers).
ROOM = ["#" * 40] + ["?" * 5 + "." * 30 + "?" * 5] * 10 + ["#" * 40]
# The same room fully known: closed at both ends.
CLOSED = ["#" * 40] + ["#" + "." * 38 + "#"] * 10 + ["#" * 40]


class Modes:
    def __init__(self, mode="navigation"):
        self.mode, self.runs_stack, self.switches = mode, True, []
        self.leaving = []

    def status(self):
        return {"mode": self.mode, "state": "running", "map": None}

    def switch(self, mode, map_name=None, pose=None):
        for callback in self.leaving:
            callback({"mode": mode})
        self.switches.append(mode)
        self.mode = mode
        return self.status()

    def wait(self, timeout):
        return True

    def when_leaving_running(self, callback):
        self.leaving.append(callback)


class Source:
    def __init__(self, g):
        self.grid = g

    def current(self):
        return 1, self.grid

    def latest(self, timeout):
        return self.current()


class Store:
    def __init__(self, path, zones=()):
        self.path, self._zones = path, list(zones)

    def zones(self):
        return self._zones


class Maps:
    save_timeout = 1.0

    def __init__(self, g, taken=()):
        self.source, self.taken, self.saved = Source(g), set(taken), []
        self.store, self.marks = Store("single.yaml"), Store("mapping.waypoints.yaml")

    def check_new_name(self, name, overwrite=False):
        if name in self.taken and not overwrite:
            raise MapExists("taken")
        return name

    def save(self, name, overwrite=False, then=None, here=None):
        self.saved.append((name, then))
        return {"status": "ok"}


class EStop:
    latched = False


class Robot:
    """Goals end as ``outcomes`` says, in order (then "active" for good); the robot stands at (1.8, 0.5)."""

    def __init__(self, outcomes=()):
        self.outcomes = list(outcomes)
        self.goals, self.canceled, self.ends = [], [], {}
        self.shutting_down, self.runs, self.estop = False, None, EStop()
        self.before_send = None
        self.lock = threading.Lock()

    def refuse_motion(self, what):
        if self.estop.latched:
            raise EStopLatched("e-stop")

    def current_pose(self):
        return Pose2D(1.8, 0.55, 0.0)

    def run_goto(self, goal):
        if self.before_send:
            self.before_send()
        with self.lock:
            self.goals.append(goal)
            seq = len(self.goals)
            self.ends[seq] = self.outcomes.pop(0) if self.outcomes else ("active", None)
            return seq

    def goal_end(self, seq, timeout):
        with self.lock:
            state = self.ends.get(seq, ("active", None))
        if state[0] == "active":
            time.sleep(min(timeout, 0.02))
        return state

    def cancel_goal(self, seq):
        self.canceled.append(seq)
        with self.lock:
            if self.ends.get(seq, ("active",))[0] == "active":
                self.ends[seq] = ("preempted", "canceled")


def explorer(robot, maps, modes=None, **kw):
    return Explorer(robot, modes or Modes(), maps, radius=0.15, progress_timeout=kw.pop("patience", 30.0), **kw)


def ended(x, timeout=10):
    wait_for(lambda: x.current()["state"] in ("done", "failed", "canceled"), timeout=timeout, message="the end")
    return x.current()


def test_an_aborted_goal_is_given_up_and_the_other_frontier_is_tried_then_it_is_done():
    robot = Robot([("aborted", "no path"), ("aborted", "no path")] + [("succeeded", None)] * 3)
    maps = Maps(grid(ROOM))
    x = explorer(robot, maps)
    x.start("flat")
    done = ended(x)
    first, second = robot.goals[0].pose, robot.goals[1].pose
    assert abs(first.x - second.x) > 1.0, "the aborted frontier was tried again"
    assert done["state"] == "done" and maps.saved == [("flat", True)]
    assert done["goals"] == 2 and len(robot.goals) == 3  # two frontiers given up, then the way home


def test_a_closed_room_is_done_at_once_and_the_robot_comes_home():
    robot = Robot([("succeeded", None)])
    maps = Maps(grid(CLOSED))
    modes = Modes()
    x = explorer(robot, maps, modes)
    x.start("flat", then="idle")
    done = ended(x)
    assert done["state"] == "done" and done["frontiers"] == 0
    assert modes.switches == ["mapping", "idle"]
    assert len(robot.goals) == 1  # home only
    assert "whole reachable flat" in done["message"]


def test_a_replaced_goal_is_not_given_up():
    robot = Robot()  # goals stay active
    maps = Maps(grid(ROOM))
    x = explorer(robot, maps)
    x.start("flat")
    wait_for(lambda: len(robot.goals) >= 1, message="a goal")
    target = robot.goals[0].pose
    # the frontier the robot drives to is seen: that end of the room is closed now
    rows = [r[:20] + r[20:].replace("?", "#") if target.x > 2.0 else r[:20].replace("?", "#") + r[20:]
            for r in ROOM]
    maps.source.grid = grid(rows)
    wait_for(lambda: len(robot.goals) >= 2, message="the next goal")
    assert robot.canceled == []  # replaced by the next goal, not canceled
    assert abs(robot.goals[1].pose.x - target.x) > 1.0
    robot.ends[2] = ("succeeded", None)
    x.cancel("test over", wait_for_send=False)


def test_stop_while_a_goal_is_being_sent_cancels_that_goal():
    robot = Robot()
    maps = Maps(grid(ROOM))
    x = explorer(robot, maps)
    robot.before_send = lambda: threading.Thread(target=x.cancel, args=("Stopped (POST /stop).", False)).start() \
        or time.sleep(0.1)
    x.start("flat")
    done = ended(x)
    assert done["state"] == "canceled" and done["message"].startswith("Stopped (POST /stop).")
    wait_for(lambda: robot.canceled == [1], timeout=2, message="the goal sent just after the stop canceled")
    assert len(robot.goals) == 1 and maps.saved == []


def test_a_mode_switch_by_someone_else_ends_it_unsaved():
    robot = Robot()
    maps, modes = Maps(grid(ROOM)), Modes()
    x = explorer(robot, maps, modes)
    x.start("flat")
    wait_for(lambda: robot.goals, message="a goal")
    modes.switch("idle")
    done = ended(x)
    assert done["state"] == "canceled" and "switched to idle" in done["message"]
    assert maps.saved == []


def test_no_progress_gives_the_frontier_up():
    robot = Robot()
    maps = Maps(grid(ROOM))
    x = explorer(robot, maps, patience=0.3)
    x.start("flat")
    wait_for(lambda: len(robot.goals) >= 2, message="a second goal after no progress")
    assert 1 in robot.canceled
    assert abs(robot.goals[0].pose.x - robot.goals[1].pose.x) > 1.0
    x.cancel("test over", wait_for_send=False)


def test_out_of_time_it_returns_and_saves_what_it_has():
    robot = Robot()
    maps = Maps(grid(ROOM))
    x = explorer(robot, maps)
    x.start("flat", max_minutes=0.01)
    wait_for(lambda: x.current()["state"] == "returning", message="returning")
    robot.ends[len(robot.goals)] = ("succeeded", None)
    done = ended(x)
    assert done["state"] == "done" and "after 0.01 minutes" in done["message"]


@pytest.mark.parametrize("why", ["taken", "estop", "run", "exploring"])
def test_refused_before_anything_moves(why):
    robot, maps, modes = Robot(), Maps(grid(ROOM), taken={"flat"} if why == "taken" else ()), Modes()
    x = explorer(robot, maps, modes)
    if why == "estop":
        robot.estop.latched = True
    if why == "run":
        robot.runs = type("Runs", (), {"active": lambda self: {"id": 3, "route": "rounds"}})()
    if why == "exploring":
        x.start("other")
        wait_for(lambda: robot.goals, message="a goal")
        modes.switches.clear()
    expected = {"taken": MapExists, "estop": EStopLatched, "run": ExploreConflict, "exploring": ExploreConflict}
    with pytest.raises(expected[why]):
        x.start("flat")
    assert modes.switches == []
    if why == "exploring":
        x.cancel("test over", wait_for_send=False)
    else:
        assert robot.goals == []


def test_no_pose_on_the_new_map_fails_with_the_reason():
    robot = Robot()
    robot.current_pose = lambda: (_ for _ in ()).throw(NoPose("no tf map -> base_link"))
    maps = Maps(grid(ROOM))
    x = explorer(robot, maps)
    x.start("flat")
    done = ended(x)
    assert done["state"] == "failed" and "no tf map" in done["message"]


@pytest.mark.parametrize("outcomes, back", [([("aborted", "stuck"), ("succeeded", None)], True),
                                            ([("aborted", "stuck"), ("aborted", "stuck")], False)])
def test_the_way_home_is_tried_twice_then_the_map_is_saved_where_it_stands(outcomes, back):
    robot, maps = Robot(outcomes), Maps(grid(CLOSED))
    x = explorer(robot, maps)
    x.start("flat")
    done = ended(x)
    assert done["state"] == "done" and maps.saved == [("flat", True)]
    assert len(robot.goals) == 2
    assert ("could not get back" in done["message"]) is not back, done["message"]


def test_a_way_home_that_gets_no_nearer_is_given_up_and_the_map_saved_where_it_stands():
    robot, maps = Robot(), Maps(grid(CLOSED))  # every goal stays active: the robot stands
    x = explorer(robot, maps, patience=0.3)
    x.start("flat")
    done = ended(x)
    assert done["state"] == "done" and maps.saved == [("flat", True)]
    assert set(robot.canceled) == {1, 2}, "each try home canceled once it got no nearer"
    assert "could not get back" in done["message"] and "no nearer" in done["message"], done["message"]


def test_a_pose_lost_while_exploring_ends_it_failed_saying_so():
    robot, maps = Robot(), Maps(grid(ROOM))
    calls = []

    def pose():
        calls.append(1)
        if len(calls) > 3:
            raise NoPose("no tf map -> base_link")
        return Pose2D(1.8, 0.55, 0.0)
    robot.current_pose = pose
    x = explorer(robot, maps, patience=0.3)
    x.start("flat")
    done = ended(x)
    assert done["state"] == "failed" and "was not known for" in done["message"], done
    assert maps.saved == []


def test_a_wall_drawn_while_mapping_is_never_driven_through_even_by_a_robot_beside_it():
    robot, maps = Robot(), Maps(grid(ROOM))
    robot.current_pose = lambda: Pose2D(2.6, 0.55, 0.0)  # 0.1 m from the wall: the open end beyond it is nearer
    maps.store = maps.marks = Store("mapping.waypoints.yaml",
                                    [make_zone("Tür", {"kind": "wall", "line": [[2.7, -0.1], [2.7, 1.3]]})])
    x = explorer(robot, maps)
    x.start("flat")
    wait_for(lambda: robot.goals, message="a first goal")
    assert robot.goals[0].pose.x < 2.7, "a goal beyond the wall: {}".format(robot.goals[0].pose)
    x.cancel("test over", wait_for_send=False)


class Flipping(Source):
    """Each look shows one end of the room closed, the other end the next time: its frontiers take turns."""

    def __init__(self):
        super().__init__(grid(ROOM))
        self.looks = 0
        self.ends = [grid([r[:20].replace("?", "#") + r[20:] for r in ROOM]),
                     grid([r[:20] + r[20:].replace("?", "#") for r in ROOM])]

    def current(self):
        self.looks += 1
        return self.looks, self.ends[self.looks % 2]


def test_two_frontiers_taking_turns_while_nothing_new_is_mapped_are_given_up_and_it_ends():
    robot, maps = Robot(), Maps(grid(ROOM))
    maps.source = Flipping()
    x = explorer(robot, maps, patience=0.3)
    x.start("flat")
    wait_for(lambda: x.current()["state"] in ("returning", "done"), timeout=10,
             message="exploring to end though each goal is replaced before it is reached")
    assert len(robot.canceled) >= 1 and len(robot.goals) >= 3
    x.cancel("test over", wait_for_send=False)


# A room 5 m x 1 m known, open at both ends and through a gap in its top wall: three frontiers.
WIDE = ["#" * 25 + "?" * 10 + "#" * 25] + ["?" * 5 + "." * 50 + "?" * 5] * 10 + ["#" * 60]


class MovingRobot(Robot):
    """As Robot, but it stands where its last goal that succeeded went (it starts at ``start``)."""

    def __init__(self, outcomes, start=(1.5, 0.55)):
        super().__init__(outcomes)
        self.pose = Pose2D(start[0], start[1], 0.0)

    def current_pose(self):
        return self.pose

    def run_goto(self, goal):
        seq = super().run_goto(goal)
        if self.ends[seq][0] == "succeeded":
            self.pose = Pose2D(goal.pose.x, goal.pose.y, 0.0)
        return seq


def test_a_robot_that_cannot_move_ends_stuck_saves_nothing_and_keeps_mapping():
    """The real stack's wedged robot: every frontier aborted where it stood. Not "the whole flat is
    mapped": after two frontiers given up without moving, a goal back to where it has been gets
    nowhere too, so the exploration ends stuck, saves nothing and leaves mapping running."""
    robot = MovingRobot([("succeeded", None), ("aborted", "no valid plan"), ("aborted", "potential collision"),
                         ("aborted", "no valid plan")])
    maps, modes = Maps(grid(WIDE)), Modes()
    x = explorer(robot, maps, modes)
    x.start("flat")
    wait_for(lambda: x.current()["state"] in ("done", "failed", "canceled", "stuck"), timeout=10, message="the end")
    end = x.current()
    assert end["state"] == "stuck", end
    assert end["message"].startswith("Stuck near x 0.6, y 0.6: drive the robot free") and "Nothing was saved" in \
        end["message"]
    assert maps.saved == [] and modes.switches == ["mapping"]  # no save, no switch: mapping goes on
    back = robot.goals[3].pose  # the check: back to where exploring began (1.5 m), not a frontier
    assert (round(back.x, 2), round(back.y, 2)) == (1.5, 0.55)
    assert end["goals"] == 3 and len(robot.goals) == 4


def test_frontiers_out_of_reach_of_a_robot_that_can_move_are_given_up_and_it_is_done():
    """The same two frontiers given up where it stood, but the robot can go back where it has been:
    they were out of reach, so exploring goes on (here: nothing left), and the map is saved."""
    robot = MovingRobot([("succeeded", None), ("aborted", "no valid plan"), ("aborted", "no valid plan")]
                        + [("succeeded", None)] * 3)
    maps = Maps(grid(WIDE))
    x = explorer(robot, maps)
    x.start("flat")
    done = ended(x)
    assert done["state"] == "done" and maps.saved == [("flat", True)]
    assert len(robot.goals) == 5  # three frontiers, the check back, the way home


def test_a_frontier_goal_that_ends_stuck_ends_the_exploration_stuck_with_the_robot_s_words():
    """The robot said it is stuck and could not get out (recovery/: the goal ends ``stuck``): the exploration
    ends stuck at once, in those words, saves nothing, and that frontier is not given up as unreachable."""
    said = "Stuck near x 0.6, y 0.6: drive it out with the joystick (or move it by hand), then send it again."
    robot = Robot([("stuck", said)])
    maps, modes = Maps(grid(ROOM)), Modes()
    x = explorer(robot, maps, modes)
    x.start("flat")
    wait_for(lambda: x.current()["state"] not in ("starting", "exploring"), timeout=10, message="the end")
    end = x.current()
    assert end["state"] == "stuck" and "It said: " + said in end["message"], end
    assert maps.saved == [] and modes.switches == ["mapping"] and len(robot.goals) == 1


def _mapping_on_disk(tmp_path, text):
    """Maps whose served store is the real marks file of the map being made, holding ``text``."""
    from flask_move_server.waypoints.store import WaypointStore

    path = tmp_path / "mapping.waypoints.yaml"
    path.write_text(text, encoding="utf-8")
    maps = Maps(grid(CLOSED))
    maps.store = maps.marks = WaypointStore(str(path))
    return maps


def test_a_map_explored_without_a_dock_gets_one_where_it_started(tmp_path):
    maps = _mapping_on_disk(tmp_path, "waypoints:\n  Küche: [0.5, 0.5, 0.0]\n")
    x = explorer(Robot([("succeeded", None)]), maps)
    x.start("flat")
    assert ended(x)["state"] == "done"
    dock = maps.store.dock()
    assert (dock.name, dock.x, dock.y) == ("dock", 1.8, 0.55)  # where the robot stood as it began
    assert "dock: dock" in (tmp_path / "mapping.waypoints.yaml").read_text()  # given to the map on saving


def test_exploring_comes_home_to_the_dock_marked_in_the_owners_words_and_keeps_it(tmp_path):
    maps = _mapping_on_disk(tmp_path, "waypoints:\n  Ladestation: [0.3, 0.4, 1.0]\ndock: Ladestation\n")
    robot = Robot([("succeeded", None)])
    x = explorer(robot, maps)
    x.start("flat")
    assert ended(x)["state"] == "done"
    home = robot.goals[-1]
    assert (home.pose.x, home.pose.y, home.target) == (0.3, 0.4, "Ladestation")
    assert [w.name for w in maps.store.all()] == ["Ladestation"]  # no second dock added
