"""The Robot facade: everything the web layer may ask of the robot.

The Flask app knows this class, not rospy: the same routes run against the
real robot and the simulated one. It composes the parts ``cli`` built and adds
the rules that span them (teleop cancels a goal, a goal ends teleop, stop ends
both and zeroes the velocity, the teleop deadman halts the motors at once, the
e-stop latch stops everything and refuses goals and teleop until released).
"""

from flask_move_server.core.errors import (
    NavigationFailed,
    NavigationUnavailable,
    NoDock,
    NotStuck,
    Pressed,
    ShuttingDown,
)
from flask_move_server.drive.estop import EStop

_SHUTTING_DOWN = "The server is shutting down: the robot was stopped. Send the command again once it is back."
STOPPED = "Stopped (POST /stop)."
ESTOP = "The e-stop was engaged ({})."
ESTOP_SOURCES = {"api": "POST /estop", "button": "its button", "mqtt": "Home Assistant (MQTT)"}
SHUT_DOWN = "The server stopped while this run was under way; resume it to go on."


class Robot:
    """One robot: navigation, teleop, pose, motors, battery, ROS health."""

    def __init__(self, node, navigator, pose, teleop, drive, estop=None, battery=None):
        """``battery``: a ros/battery.py BatteryMonitor (``status()`` and ``close()``), or None."""
        self.node = node
        self.navigator = navigator
        self.pose = pose
        self.teleop_control = teleop
        self.drive = drive
        self.estop = estop if estop is not None else EStop()
        self.battery = battery
        # A zero Twist is ramped down by the base; a deadman that runs out must stop at once.
        teleop.on_expire(drive.stop)
        self.estop.when_engaged(lambda source: self.stop(ESTOP.format(ESTOP_SOURCES.get(source, source))))
        self.shutting_down = False
        self.runs = None  # missions/executor.py: the run under way, ended by any other command
        self.explorer = None  # explore/explorer.py: an exploration under way, ended by any other command too
        self.goal_gate = None  # modes/goal_gate.py, when this server runs the navigation stack
        self.ground_truth = None  # with --sim: the simulated robot's true pose (a callable), shown in /status
        self.recovery = None  # recovery/recovery.py: the stuck state, told of every goal and stop
        self.docking = None  # dock/docking.py: home to the charger; a goal while docked backs off it first
        self.zones = None  # zones/guard.py: goals in a zone the robot keeps out of are refused

    def goto(self, goal, via="POST /goto"):
        """Send the robot to ``goal``; returns the goal's sequence number. Ends a run under way, saying
        the goal came ``via`` (the API, Home Assistant)."""
        return self._send(goal, "A goal to {} ({}) took the robot elsewhere.".format(goal.target or "a pose", via))

    def run_goto(self, goal):
        """A run's goal: as :meth:`goto`, but part of the run (it ends none), and never waiting for move_base."""
        if not self.navigator.server_ready():
            self.navigator.check_ros()
            raise NavigationUnavailable("move_base does not answer, so the run's goal could not be sent.")
        return self._send(goal, None)

    def dock_goal(self, goal):
        """The docking's own goal (to the staging pose before the charger): as :meth:`run_goto`, ending nothing."""
        return self._send(goal, None, docking=True)

    def goal_end(self, seq, timeout):
        """``(state, why)`` of goal ``seq`` once it ends or after ``timeout`` s (``active`` then); never raises."""
        return self.navigator.wait(seq, timeout)

    def _send(self, goal, ends_run, docking=False):
        self._refuse_motion("goals are")
        self.check_zones(goal.pose, goal.target)  # before anything moves or ends: 409 in_zone
        if self.docking is not None and not docking:
            self.docking.before_goal()  # off the charger first: move_base plans nothing from on top of it
        ticket = None
        if self.goal_gate is not None:
            self.navigator.check_ros()  # ROS down is the first reason, whatever the mode says
            ticket = self.goal_gate.admit()
        if ends_run:
            self._end_run(ends_run)
        self.drive.rearm()  # a deliberate command: motion after an e-stop release starts here
        seq = self.navigator.goto(goal)
        if self.goal_gate is not None:
            self.goal_gate.confirm(ticket, seq)
        self.teleop_control.end_command()
        if self.recovery is not None:
            self.recovery.goal_sent(seq)
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

    def stop(self, reason=STOPPED):
        """End the run under way (saying ``reason``), cancel the goal, end teleop, command zero velocity.

        Never waits for a run's goal being sent: the run notices it was ended and cancels that goal itself.
        """
        self._end_run(reason, wait_for_send=False)
        canceled = self.halt()
        if self.recovery is not None:
            self.recovery.commanded()
        return canceled

    def halt_for(self, reason):
        """As :meth:`halt`, and an exploration under way ends with ``reason``; a run is left as it is (paused)."""
        if self.explorer is not None:
            self.explorer.cancel(reason, False)
        return self.halt()

    def halt(self):
        """Cancel the goal, end teleop, command zero velocity; a run under way is left as it is (its pause)."""
        canceled = self.navigator.cancel()
        self.teleop_control.stop()
        self.drive.stop()
        return canceled

    def _end_run(self, reason, wait_for_send=True):
        """Someone else commands the robot: the run (or exploration) under way ends ``canceled`` with ``reason``.

        ``wait_for_send``: for a command about to send motion of its own, so that a goal the run is
        sending goes first and is replaced, never the other way round.
        """
        if self.runs is not None:
            self.runs.end_by(reason, wait_for_send)
        if self.explorer is not None:
            self.explorer.cancel(reason, wait_for_send)
        if self.docking is not None:
            self.docking.ended_by(reason)

    def cancel_goal(self, seq):
        """Cancel goal ``seq`` if it is still the one under way (a run's, paused or ended); zero velocity then."""
        if self.navigator.cancel(seq):
            self.drive.stop()

    def busy_with(self):
        """Why the robot is busy with something a schedule must not cut short (a goal, the joystick), or None."""
        teleop = self.teleop_control.status()
        if self.docking is not None and self.docking.status()["state"] in ("going", "approaching", "undocking"):
            return "The robot was docking at its charger."
        if teleop["active"]:
            return ("The robot was backing out of a tight spot." if teleop.get("by") == "back_out"
                    else "The robot was being driven by joystick.")
        if self.navigator.active:
            target = self.navigator.status().get("target")
            return "The robot was on its way to {}.".format(target or "a goal")
        return None

    def refuse_motion(self, what):
        """EStopLatched (or ShuttingDown) when nothing may move now: ``what`` names the refused thing."""
        self._refuse_motion(what)

    def shutdown(self):
        """The server is stopping: stop first, refuse motion, answer every waiting /goto (ShuttingDown)."""
        self.shutting_down = True
        self.navigator.trips = None  # the stop below ends the trip, but a restart must still say it cut one short
        if self.runs is not None:
            self.runs.interrupt(SHUT_DOWN)  # not canceled: the run is resumable after the restart
        if self.explorer is not None:
            self.explorer.cancel("The server stopped while exploring.", wait_for_send=False)
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
        if self.recovery is not None:
            self.recovery.check_push(linear)
        self._end_run("Driven by joystick (POST /teleop).")
        if self.docking is not None:
            self.docking.driven_off()
        if self.recovery is not None:
            self.recovery.owner_drives()
        self.drive.rearm()  # a deliberate command: motion after an e-stop release starts here
        result = self.teleop_control.command(linear, angular)
        if self.navigator.active:
            self.navigator.cancel()
            result["canceled_goal"] = True
        self._unless_latched_meanwhile()
        self._unless_pressed_meanwhile(linear)
        return result

    def _unless_pressed_meanwhile(self, linear):
        """Found pressed against something while this push was on its way: it ends too, and is refused."""
        if self.recovery is None:
            return
        try:
            self.recovery.check_push(linear)
        except Pressed:
            self.teleop_control.stop()
            raise

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
            "battery": self.battery_status(),
            "stuck": self.stuck_status(),
            "dock": self.dock_status(),
            "ros": {"state": self.node.health, "master_uri": self.node.master_uri, "node": self.node.name,
                    "failed_parts": self.node.failed_parts},
            **self._simulated(),
        }

    def back_out(self):
        """Back out of where the robot said it is stuck (it waits for its owner): NotStuck when it is not."""
        if self.recovery is None:
            raise NotStuck("The stuck watch is off (stuck.enabled: false): drive the robot with the joystick.")
        self.recovery.back_out()
        return self.recovery.status()

    def dock(self):
        """Home to the charger and onto it (dock/docking.py): the dock status. NoDock without a charger."""
        self._check_docking()
        return self.docking.dock()

    def undock(self):
        """Back straight off the charger: the dock status. DockFailed when not on one."""
        self._check_docking()
        return self.docking.undock()

    def check_zones(self, pose, target=None):
        """InZone when ``pose`` lies in (or too near) an enabled zone of the map (zones/guard.py)."""
        if self.zones is not None:
            self.zones.check(pose, target)

    def dock_status(self):
        """``/status`` ``dock`` (dock/docking.py), or None on a robot built without docking."""
        return self.docking.status() if self.docking is not None else None

    def _check_docking(self):
        if self.docking is None:
            raise NoDock("This server was started without docking.")

    def stuck_status(self):
        """``/status`` ``stuck`` (recovery/recovery.py), or None when the stuck watch is off."""
        return self.recovery.status() if self.recovery is not None else None

    def battery_status(self):
        """``{"percentage", "voltage", "charging", "age"}`` of the battery's last reading, or None (never heard)."""
        return self.battery.status() if self.battery is not None else None

    def _simulated(self):
        """``{"sim": {"true_pose": ...}}`` with --sim: where the robot really is, beside what localization believes."""
        if self.ground_truth is None:
            return {}
        return {"sim": {"true_pose": self.ground_truth().as_dict()}}

    def health(self):
        """The short answer of ``GET /health``."""
        body = {
            "status": "ok",
            "ros": self.node.health,
            "move_base": "ready" if self.takes_goals() else "unavailable",
        }
        note = self.goal_gate.health_note() if self.goal_gate is not None else None
        if note:
            body["note"] = note
        return body

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
        if self.battery is not None:
            self.battery.close()
