"""The trip under way kept on disk (trip_record.py): a restart says which trip it interrupted."""

import json

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
