"""The Robot facade: everything the web layer may ask of the robot.

The Flask app knows this class, not rospy: the same routes run against the
real robot and the simulated one. It composes the parts ``cli`` built and adds
the rules that span them (teleop cancels a goal, a goal ends teleop, stop ends
both and zeroes the velocity, the teleop deadman halts the motors at once, the
e-stop latch stops everything and refuses goals and teleop until released).
"""

from flask_move_server.drive.estop import EStop
from flask_move_server.errors import NavigationFailed, ShuttingDown

_SHUTTING_DOWN = "The server is shutting down: the robot was stopped. Send the command again once it is back."


class Robot:
    """One robot: navigation, teleop, pose, motors, ROS health."""

    def __init__(self, node, navigator, pose, teleop, drive, estop=None):
        self.node = node
        self.navigator = navigator
        self.pose = pose
        self.teleop_control = teleop
        self.drive = drive
        self.estop = estop if estop is not None else EStop()
        # A zero Twist is ramped down by the base; a deadman that runs out must stop at once.
        teleop.on_expire(drive.stop)
        self.estop.when_engaged(lambda source: self.stop())
        self.shutting_down = False
        self.goal_gate = None  # modes/goal_gate.py, when this server runs the navigation stack
        self.ground_truth = None  # with --sim: the simulated robot's true pose (a callable), shown in /status

    def goto(self, goal):
        """Send the robot to ``goal``; returns the goal's sequence number."""
        self._refuse_motion("goals are")
        ticket = None
        if self.goal_gate is not None:
            self.navigator.check_ros()  # ROS down is the first reason, whatever the mode says
            ticket = self.goal_gate.admit()
        self.drive.rearm()  # a deliberate command: motion after an e-stop release starts here
        seq = self.navigator.goto(goal)
        if self.goal_gate is not None:
            self.goal_gate.confirm(ticket, seq)
        self.teleop_control.end_command()
        self._unless_latched_meanwhile()
        return seq

    def wait(self, seq, timeout):
        """Wait up to ``timeout`` s for goal ``seq``; True when reached, False when still under way.

        NavigationFailed says how it ended otherwise, naming its own target even when a newer
        goal has taken its place since.
        """
        state, why = self.navigator.wait(seq, timeout)
        self._check_running()
        if state == "succeeded":
            return True
        if state == "active":
            return False
        raise NavigationFailed(state, why)

    def navigation_status(self):
        """The goal's state as ``/status`` shows it under ``navigation`` (the pose is not read)."""
        return self.navigator.status()

    def stop(self):
        """Cancel the goal, end teleop, command zero velocity."""
        canceled = self.navigator.cancel()
        self.teleop_control.stop()
        self.drive.stop()
        return canceled

    def shutdown(self):
        """The server is stopping: stop first, refuse motion, answer every waiting /goto (ShuttingDown)."""
        self.shutting_down = True
        self.navigator.trips = None  # the stop below ends the trip, but a restart must still say it cut one short
        self.stop()
        self.navigator.release_waiters()

    def _check_running(self):
        if self.shutting_down:
            raise ShuttingDown(_SHUTTING_DOWN)

    def _refuse_motion(self, what):
        self._check_running()
        self.estop.refuse_motion(what)

    def teleop(self, linear, angular):
        """Drive at the given velocity for the deadman time; cancels a goal under way."""
        self._refuse_motion("teleop is")
        self.drive.rearm()  # a deliberate command: motion after an e-stop release starts here
        result = self.teleop_control.command(linear, angular)
        if self.navigator.active:
            self.navigator.cancel()
            result["canceled_goal"] = True
        self._unless_latched_meanwhile()
        return result

    def _unless_latched_meanwhile(self):
        """An e-stop or a shutdown came while a goal or command was on its way: stop that one too, and refuse."""
        if self.estop.latched or self.shutting_down:
            self.stop()
            self._refuse_motion("goals and teleop are")

    def engage_estop(self, source):
        """Latch the e-stop: everything stops, goals and teleop are refused. True when newly latched."""
        return self.estop.engage(source)

    def release_estop(self):
        """Lift the e-stop latch; True when it was latched; EStopHeld while the button is still pressed."""
        return self.estop.release()

    def estop_status(self):
        """The latch's state, as ``/status`` shows it under ``estop``."""
        return self.estop.status()

    def current_pose(self):
        """The robot's pose in the map frame now; NoPose when unknown or stale."""
        return self.pose.fresh(
            "The robot's pose is not known: no tf map → base_link and no /amcl_pose yet. "
            "Is localization (AMCL) running and the robot's initial pose set?"
        )

    def status(self):
        """Everything ``GET /status`` shows."""
        reading = self.pose.current() if self.node.connected else None  # one pose for both answers
        return {
            "pose": self.pose.as_dict(reading) if reading else None,
            "navigation": self.navigator.status(reading),
            "teleop": self.teleop_control.status(),
            "motors": self.drive.status(),
            "estop": self.estop.status(),
            "ros": {"state": self.node.health, "master_uri": self.node.master_uri, "node": self.node.name,
                    "failed_parts": self.node.failed_parts},
            **self._simulated(),
        }

    def _simulated(self):
        """``{"sim": {"true_pose": ...}}`` with --sim: where the robot really is, beside what localization believes."""
        if self.ground_truth is None:
            return {}
        return {"sim": {"true_pose": self.ground_truth().as_dict()}}

    def health(self):
        """The short answer of ``GET /health``."""
        return {
            "status": "ok",
            "ros": self.node.health,
            "move_base": "ready" if self.takes_goals() else "unavailable",
        }

    def takes_goals(self):
        """True when a goal sent now would be taken: move_base answers, and the mode runs (never waits)."""
        gate = self.goal_gate
        return self.navigator.server_ready() and (gate is None or gate.open_now())

    def close(self):
        """Stop moving, then release the ROS connections and the teleop thread. Idempotent."""
        self.stop()
        self.teleop_control.close()
        self.navigator.close()
        self.pose.close()
