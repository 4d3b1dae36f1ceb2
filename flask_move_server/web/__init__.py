"""The Flask app: ``create_app(config, robot, store)``.

Shared objects live in ``app.extensions["flask_move_server"]``, never in a
module global, so several apps (tests) can live in one process.
"""

from flask import Blueprint, Flask, Response, send_from_directory
from flask.sessions import NullSession, SessionInterface

from flask_move_server.core.events import EventBus
from flask_move_server.modes.manager import ModeManager
from flask_move_server.process import ast_guard
from flask_move_server.web import auth, error_handlers, guard
from flask_move_server.web.diagnostics import diagnostics_api
from flask_move_server.web.dock import docking
from flask_move_server.web.estop import estop
from flask_move_server.web.events import events_api
from flask_move_server.web.explore import explore_api
from flask_move_server.web.maps import maps_api
from flask_move_server.web.missions import missions_api
from flask_move_server.web.modes import modes as modes_routes
from flask_move_server.web.openapi import description
from flask_move_server.web.routes import WaypointNameConverter, api
from flask_move_server.web.stuck import stuck
from flask_move_server.web.zones import zones_api

ast_guard.serialise_ast_parse()  # werkzeug parses each route while ROS threads may format tracebacks


class RobotApp(Flask):
    """Flask, asking once per view or hook whether it is a coroutine, not on every request.

    Flask's ``ensure_sync`` asks ``inspect`` about each view and ``before_request`` hook each time
    it runs one; on a ``/goto`` that was more Python than the goal's own checks. The answer never
    changes for a function, so it is kept.
    """

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._sync_functions = {}

    def ensure_sync(self, func):
        sync = self._sync_functions.get(func)
        if sync is None:
            sync = self._sync_functions[func] = super().ensure_sync(func)
        return sync


class NoSessions(SessionInterface):
    """The API keeps no sessions: every request gets the same empty, read-only one (Flask would build one each)."""

    _none = NullSession()

    def open_session(self, app, request):
        return self._none

    def save_session(self, app, session, response):
        return None


class UntypedResponse(Response):
    """A response with no Content-Type unless it sets one.

    Every answer with a body is JSON or a static file and says so; Flask would label the empty
    ones (204, the automatic ``OPTIONS``) ``text/html``, which they are not.
    """

    default_mimetype = None


def create_app(config, robot, store, token=None, events=None, modes=None, maps=None, doctor=None, runs=None,
               explorer=None):
    """Build the WSGI app serving ``robot`` and the waypoints in ``store``; ``events``: the server's bus.

    ``modes``: the server's ModeManager (None: modes are off, the stack runs outside this server).
    ``maps``: the :class:`~flask_move_server.maps.service.MapService` behind ``/map`` and ``/maps``
    (default: the configured maps folder, no live map, no mode manager).
    ``doctor``: the :class:`~flask_move_server.diagnostics.doctor.Doctor` behind ``/diagnostics``.
    ``runs``: the :class:`~flask_move_server.missions.executor.RunExecutor` behind ``/runs``.
    ``explorer``: the :class:`~flask_move_server.explore.explorer.Explorer` behind ``/explore`` (None: this
    server does not explore; ``POST /explore`` answers 409).
    """
    events = events if events is not None else EventBus()
    modes = modes if modes is not None else ModeManager(config, None)
    maps = maps if maps is not None else _folder_only_maps(config, store, events)
    app = RobotApp(__name__, static_folder="static", static_url_path="/static")
    app.response_class = UntypedResponse
    app.session_interface = NoSessions()
    app.url_map.converters["waypoint"] = WaypointNameConverter
    app.url_map.merge_slashes = False  # /waypoints//a is the name "/a" (a 400), not an HTML redirect
    app.config["MAX_CONTENT_LENGTH"] = config.server.max_body_bytes
    app.json.sort_keys = False
    # Names as typed ("Küche", not "K\u00fcche"), in UTF-8 said out loud: clients that guess
    # otherwise (Windows PowerShell 5's Invoke-RestMethod reads Latin-1) read them right too.
    app.json.ensure_ascii = False
    app.json.mimetype = "application/json; charset=utf-8"
    app.extensions["flask_move_server"] = {
        "config": config, "robot": robot, "store": store, "events": events, "maps": maps, "modes": modes,
        "doctor": doctor, "runs": runs, "explorer": explorer}
    error_handlers.init_app(app)
    guard.init_app(app, config)  # before auth: it protects robots without a token too
    auth.init_app(app, token)
    app.register_blueprint(api)
    app.register_blueprint(estop)
    app.register_blueprint(stuck)
    app.register_blueprint(docking)
    app.register_blueprint(zones_api)
    app.register_blueprint(maps_api)
    app.register_blueprint(missions_api)
    app.register_blueprint(explore_api)
    app.register_blueprint(events_api)
    app.register_blueprint(description)
    app.register_blueprint(modes_routes)
    app.register_blueprint(diagnostics_api)
    if config.server.static:
        _add_page(app)
    return app


def _folder_only_maps(config, store, events):
    from flask_move_server.maps.catalogue import MapCatalogue
    from flask_move_server.maps.service import MapService

    return MapService(MapCatalogue(config.maps_folder()), store, events=events, margin=config.maps.image_margin,
                      save_timeout=config.maps.save_timeout)


def _add_page(app):
    page = Blueprint("page", __name__)

    @page.route("/", methods=["GET"])
    def index():
        return send_from_directory(app.static_folder, "index.html")

    app.register_blueprint(page)
