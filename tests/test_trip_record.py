"""The trip under way kept on disk (trip_record.py): a restart says which trip it interrupted."""

import json

import pytest

from flask_move_server.core.geometry import Goal, Pose2D
from flask_move_server.core.trip_record import TripRecord
from tests.conftest import wait_for


def test_a_trip_is_kept_while_under_way_and_forgotten_when_it_ends(tmp_path):
    path = tmp_path / "trip.json"
    record = TripRecord(str(path))
    try:
        record.started(Goal(Pose2D(1.5, 2.0, 0.0), "kitchen"))
        wait_for(path.exists, timeout=5, message="the trip written")
        assert json.loads(path.read_text())["target"] == "kitchen"
        record.ended()
        wait_for(lambda: not path.exists(), timeout=5, message="the trip removed once it ended")
    finally:
        record.close()


def test_a_trip_left_by_a_stop_mid_way_is_told_once_after_the_restart(tmp_path):
    path = tmp_path / "trip.json"
    first = TripRecord(str(path))
    first.started(Goal(Pose2D(1.5, 2.0, 0.0), "Küche"))
    first.close()  # the server stopped with the robot on its way
    again = TripRecord(str(path))
    try:
        said = again.left_over()
        assert said.startswith("The trip to Küche was interrupted") and "restarted" in said
        wait_for(lambda: not path.exists(), timeout=5, message="the note removed once told")
        assert again.left_over() is None
    finally:
        again.close()


def test_a_trip_to_a_pose_names_the_pose_and_a_broken_note_is_ignored(tmp_path):
    path = tmp_path / "trip.json"
    record = TripRecord(str(path))
    record.started(Goal(Pose2D(3.25, -1.0, 0.0)))
    record.close()
    again = TripRecord(str(path))
    said = again.left_over()
    assert "x 3.2, y -1.0" in said or "x 3.3, y -1.0" in said, said
    again.close()
    path.write_text("{not json")
    third = TripRecord(str(path))
    assert third.left_over() is None
    third.close()



@pytest.mark.parametrize("note, told", [
    ({"goal": {"x": "a", "y": 1}}, "The trip to a goal was"),  # crashed the server's start: "{:.1f}" of text
    ({"goal": [1, 2]}, "The trip to a goal was"),  # crashed it too: a list has no .get
    ({"goal": {"x": 1e308, "y": 0}}, "The trip to a goal was"),
    ({"target": "x" * 3000, "goal": {"x": 1.0, "y": 2.0}}, "The trip to x 1.0, y 2.0 was"),
    ({"target": "a\\nb\u202e", "goal": None}, "The trip to a goal was"),
    ({"target": 5}, "The trip to a goal was"),
])
def test_a_hand_edited_note_is_checked_as_the_api_checks_a_goal(tmp_path, note, told):
    """Issue 34: every value read from a state file passes the API's checks."""
    path = tmp_path / "trip.json"
    path.write_text(json.dumps(note))
    record = TripRecord(str(path))
    try:
        assert record.left_over().startswith(told)
    finally:
        record.close()
