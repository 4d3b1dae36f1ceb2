"""The commands Home Assistant (or any MQTT client the broker lets in) sends the robot.

Each goes through the same checks and into the same code paths as its HTTP twin: a goto is
``Robot.goto`` (the e-stop latch, the mode's goal gate, an unknown waypoint refuse it), a route is
a run of the one executor (trigger ``mqtt``), Stop is ``Robot.stop``. A refusal is kept as
``refused`` ({"command", "message", "at"}) for the state topic, where Home Assistant shows it on
the Status sensor's attributes; the next command that is taken clears it. Pure: no paho, no rospy.
"""

import datetime
import logging

from flask_move_server.core.errors import BadRequest, MoveServerError, RunConflict, UnknownZone, shown
from flask_move_server.core.geometry import Goal, Pose2D
from flask_move_server.process.log_limits import Throttled
from flask_move_server.zones import zone_object_id

log = logging.getLogger(__name__)

SET, PRESS = "set", "press"
STOPPED = "Stopped from Home Assistant (MQTT)."
VIA = "MQTT {}"  # who sent a goal that ended a run, as the run's end says: "MQTT goto/set"
LINES_BURST = 20  # command lines logged per 10 s (as the navigator's goal lines); the rest of a flood is counted
MAX_NAME = 256  # characters of a waypoint or route name taken (a name is at most 64; more is refused by its check)


class Commands:
    """``<root>/goto/set``, ``route/set``, ``stop/press``, ``dock/press``, ``pause/press``,
    ``resume/press``, ``estop/press``, ``zone/<id>/set`` on ``link``, acted on through the robot, the run
    executor and the waypoint store."""

    def __init__(self, link, robot, store, runs, changed=lambda: None, clock=None):
        self._robot, self._store, self._runs = robot, store, runs
        self._changed = changed  # the state topic tells the refusal (or its end)
        self._clock = clock or _utc_now
        self.refused = None
        self._lines = Throttled(log, "MQTT command lines", burst=LINES_BURST)  # a flood: not ~1000 lines/s
        for name, kind, act in (("goto", SET, self.goto), ("route", SET, self.route), ("stop", PRESS, self.stop),
                                ("dock", PRESS, self.dock), ("pause", PRESS, self.pause),
                                ("resume", PRESS, self.resume), ("estop", PRESS, self.estop)):
            link.handle("{}/{}/{}".format(link.root, name, kind), self._guarded(name, act))
        self._zone_prefix = link.root + "/zone/"
        link.handle(self._zone_prefix + "+/set", self._zone_switch)

    def _guarded(self, name, act):
        def command(payload):
            try:
                act(payload.strip())
            except MoveServerError as exc:
                self._refuse(name, str(exc))
            else:
                self._taken()
        return command

    # the commands ------------------------------------------------------------

    def goto(self, name, topic="goto/set"):
        waypoint = self._store.get(name[:MAX_NAME])  # UnknownWaypoint, with close names
        target = Goal(Pose2D(waypoint.x, waypoint.y, waypoint.yaw), waypoint.name)
        seq = self._robot.goto(target, via=VIA.format(topic))
        self._lines.info("MQTT: goal %d to %s", seq, waypoint.name)

    def _zone_switch(self, payload, topic):
        """A zone's switch (``<root>/zone/<object id>/set``, ON or OFF): the zone of that id kept out or not."""
        object_id = topic[len(self._zone_prefix):-len("/set")]
        self._guarded("zone", lambda text: self.zone(object_id, text))(payload)

    def zone(self, object_id, payload):
        if payload not in ("ON", "OFF"):
            raise BadRequest("A zone's switch takes ON or OFF, not {}.".format(shown(payload[:MAX_NAME])))
        zone = next((z for z in self._store.zones() if zone_object_id(z.name) == object_id), None)
        if zone is None:
            raise UnknownZone("No zone of this map has that switch (it was deleted or renamed).")
        self._store.switch_zone(zone.name, payload == "ON")
        self._lines.info("MQTT: zone %s %s", zone.name, "kept out" if payload == "ON" else "allowed")

    def dock(self, _payload):
        """The Dock button: home onto the map's charger, whatever its name (dock/docking.py); NoDock without one."""
        status = self._robot.dock()
        self._lines.info("MQTT: docking at %s", status["place"])

    def route(self, name):
        route = self._store.get_route(name[:MAX_NAME])
        run = self._runs.start(route, "mqtt")
        self._lines.info("MQTT: run %d of %s", run["id"], route.name)

    def stop(self, _payload):
        self._robot.stop(STOPPED)

    def estop(self, _payload):
        self._robot.engage_estop("mqtt")

    def pause(self, _payload):
        run = self._runs.active()
        if run is None or run["state"] != "running":
            raise RunConflict("No run is under way to pause.")
        self._runs.pause(run["id"])

    def resume(self, _payload):
        run = self._runs.active() or self._interrupted()
        if run is None:
            raise RunConflict("No paused or interrupted run to resume.")
        self._runs.resume(run["id"])

    def _interrupted(self):
        return next((r for r in self._runs.runs() if r["state"] == "interrupted"), None)

    # the refusal shown in Home Assistant -------------------------------------

    def _refuse(self, name, message):
        self._lines.info("MQTT: %s refused: %s", name, message)
        self.refused = {"command": name, "message": message, "at": self._clock()}
        self._changed()

    def _taken(self):
        if self.refused is not None:
            self.refused = None
            self._changed()


def _utc_now():
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
