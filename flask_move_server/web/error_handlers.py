"""One error shape on the wire, and the one place that maps errors to statuses.

``{"status": "error", "error": "<code>", "message": "<sentence a user can act on>"}``
for every failure: our own exceptions, Flask's HTTP errors (404, 405, 413...)
and, as a last resort, anything unexpected (500, logged with its traceback).
Never an HTML error page.
"""

import logging

from flask import jsonify, request
from werkzeug.exceptions import HTTPException

from flask_move_server.core import errors

log = logging.getLogger(__name__)

STATUS = (
    (errors.Unauthorized, 401),
    (errors.UnknownHost, 403),
    (errors.ForbiddenOrigin, 403),
    (errors.UnknownWaypoint, 404),
    (errors.UnknownMap, 404),
    (errors.UnknownRoute, 404),
    (errors.UnknownRun, 404),
    (errors.UnknownZone, 404),
    (errors.NoMap, 404),
    (errors.BodyTooLarge, 413),
    (errors.BadRequest, 400),
    (errors.NavigationFailed, 409),
    (errors.WaypointExists, 409),
    (errors.WaypointInUse, 409),
    (errors.MapFull, 409),
    (errors.RunConflict, 409),
    (errors.NotStuck, 409),
    (errors.Pressed, 409),
    (errors.NoDock, 409),
    (errors.DockFailed, 409),
    (errors.BatteryCritical, 409),
    (errors.InZone, 409),
    (errors.ExploreConflict, 409),
    (errors.NoPose, 409),
    (errors.WaypointsLocked, 503),
    (errors.WaypointFileError, 409),
    (errors.EStopLatched, 409),
    (errors.EStopHeld, 409),
    (errors.MapExists, 409),
    (errors.MapInUse, 409),
    (errors.MapConfigured, 409),
    (errors.ModeSwitching, 409),
    (errors.ModesOff, 409),
    (errors.WrongMode, 409),
    (errors.DiagnosticsBusy, 409),
    (errors.CommandLate, 409),
    (errors.MapFileError, 503),
    (errors.StackFailed, 503),
    (errors.TooManyStreams, 503),
    (errors.RosUnavailable, 503),
    (errors.NavigationUnavailable, 503),
    (errors.DriveError, 503),
    (errors.ShuttingDown, 503),
    (errors.MapNotReceived, 503),
)

PATH_SHOWN = 80  # characters of an unknown path quoted back in its 404

_HTTP_CODES = {
    400: ("bad_request", "The request is malformed."),
    404: ("not_found", None),  # the message names the API's paths, read from the app's routes
    405: ("method_not_allowed", "This endpoint does not take that method."),
    413: ("body_too_large", "The request body is too large."),
}


def error_response(status, code, message, **extra):
    body = {"status": "error", "error": code, "message": message}
    body.update(extra)
    response = jsonify(body)
    response.status_code = status
    return response


def status_of(exc):
    for cls, status in STATUS:
        if isinstance(exc, cls):
            return status
    return 500


def init_app(app):
    """Register the JSON error handlers on ``app``."""

    @app.errorhandler(errors.MoveServerError)
    def _ours(exc):
        status = status_of(exc)
        extra = {}
        if isinstance(exc, errors.UnknownWaypoint):
            extra["suggestions"] = exc.suggestions
        if isinstance(exc, errors.NavigationFailed):
            extra["state"] = exc.state
        response = error_response(status, exc.code, str(exc), **extra)
        if status == 401:
            response.headers["WWW-Authenticate"] = 'Bearer realm="flask-move-server"'
        return response

    @app.errorhandler(HTTPException)
    def _http(exc):
        code, message = _HTTP_CODES.get(exc.code, (exc.name.lower().replace(" ", "_"), exc.description))
        if exc.code == 404:
            message = _no_such_endpoint()
        allowed = sorted(set(getattr(exc, "valid_methods", None) or ()) - {"HEAD", "OPTIONS"})
        if exc.code == 405 and allowed:
            message = "{} takes {}, not {}.".format(_shown_path(), " or ".join(allowed), request.method[:16])
        response = error_response(exc.code, code, message)
        if exc.code == 405 and exc.valid_methods:
            response.headers["Allow"] = ", ".join(exc.valid_methods)
        return response

    paths = []  # the API's top-level paths, read from the routes at the first 404 (all are added by then)

    def _no_such_endpoint():
        if not paths:
            tops = {"/" + rule.rule.split("/")[1] for rule in app.url_map.iter_rules()}
            paths.extend(sorted(tops - {"/", "/static"}))
        shown = _shown_path()
        meant = _without_trailing_slash()
        if meant:
            return "No such endpoint: {}. Did you mean {} (no slash at the end)?".format(shown, meant)
        return "No such endpoint: {}. The API has {} (GET /openapi.json describes each).".format(
            shown, ", ".join(paths))

    def _without_trailing_slash():
        """The request's path without its trailing slashes, when that is a route for its method."""
        path = request.path.rstrip("/")
        if not path or path == request.path:
            return None
        try:
            app.url_map.bind("robot").match(path, method=request.method)
        except HTTPException:  # no such route either, or another method (a redirect is one too)
            return None
        return path if len(path) <= PATH_SHOWN else None

    @app.errorhandler(Exception)
    def _unexpected(exc):
        log.exception("unexpected error serving a request")
        return error_response(500, "internal_error", "The server failed unexpectedly; its log has the details.")


def _shown_path():
    """The request's path as an error quotes it, cut to ``PATH_SHOWN`` characters."""
    return request.path if len(request.path) <= PATH_SHOWN else request.path[:PATH_SHOWN] + "…"
