"""robotctl with a stuck robot: ``goto --wait`` waits while the robot backs itself out and fails with its
words when it could not; ``status`` says it is stuck; ``back-out`` asks it to back out. A scripted robot
(GET /status answers in turn), since what is tested is what robotctl makes of them."""

import pytest

from flask_move_server.robotctl import cli
from flask_move_server.robotctl.api import ClientError, ExitStatus
from flask_move_server.robotctl.text import describe_status

HELD = {"state": "backing_out", "message": "Stuck near sofa: backing out 30 cm slowly, then trying again.",
        "waiting": False}
GAVE_UP = {"state": "stuck", "message": "Stuck near sofa: drive it out with the joystick, then send it again.",
           "waiting": True}


class Scripted:
    def __init__(self, *statuses):
        self.statuses, self.posted = list(statuses), []

    def get(self, path):
        return self.statuses.pop(0) if len(self.statuses) > 1 else self.statuses[0]

    def post(self, path, body=None):
        self.posted.append(path)
        return {"stuck": dict(HELD, message="Stuck near sofa: backing out 30 cm slowly.")}


def status(state, stuck=None, goal_id=7):
    return {"navigation": {"state": state, "goal_id": goal_id, "target": "office", "distance_remaining": 2.0,
                           "message": stuck["message"] if stuck and state == "stuck" else None},
            "stuck": stuck or {"state": "free", "waiting": False}}


@pytest.fixture(autouse=True)
def quick(monkeypatch):
    monkeypatch.setattr(cli, "POLL_PERIOD", 0.0)


def test_goto_wait_goes_on_while_the_robot_backs_itself_out():
    robot = Scripted(status("active"), status("stuck", HELD), status("stuck", HELD), status("active"),
                     status("succeeded"))
    assert cli.follow_goal(robot, 7, "office") == ExitStatus.OK


def test_goto_wait_fails_with_the_robot_s_words_when_it_could_not_get_out():
    robot = Scripted(status("active"), status("stuck", HELD), status("stuck", GAVE_UP))
    with pytest.raises(ClientError) as failed:
        cli.follow_goal(robot, 7, "office")
    assert str(failed.value) == GAVE_UP["message"] and failed.value.exit_status == ExitStatus.ABORTED


def test_status_says_it_is_stuck_and_how_to_back_it_out(capsys):
    lines = describe_status(status("stuck", GAVE_UP), "http://robot.local:5000")
    assert "stuck:      " + GAVE_UP["message"] + " ('robotctl back-out' backs it out)" in lines
    assert not any(line.startswith("stuck:") for line in describe_status(status("active"), "url"))
    robot = Scripted(status("stuck", GAVE_UP))
    assert cli.cmd_back_out(robot, None) == ExitStatus.OK
    assert robot.posted == ["/stuck/back_out"] and "backing out: Stuck near sofa" in capsys.readouterr().out
