"""Missions: routes (ordered waypoints with loops, dwell, a failure policy and a timetable), runs
of them, and schedules. One executor (:mod:`~flask_move_server.missions.executor`) drives every
run, whoever asked for it: the HTTP API, the phone page, a schedule, and later MQTT and VDA 5050.
"""
