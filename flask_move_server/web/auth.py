"""Bearer-token auth: every request but ``GET /health``, ``GET /openapi.json`` and the page's files."""

import hmac

from flask import request

from flask_move_server.core.errors import Unauthorized

OPEN_ENDPOINTS = frozenset({"api.health", "openapi.openapi", "static", "page.index"})


def init_app(app, token):
    """Require ``Authorization: Bearer <token>`` on ``app`` when ``token`` is set."""
    if not token:
        return
    expected = token.encode("utf-8")

    @app.before_request
    def _check_token():
        if request.endpoint in OPEN_ENDPOINTS and request.method in ("GET", "HEAD"):
            return None
        scheme, _, given = request.headers.get("Authorization", "").partition(" ")
        if scheme.lower() != "bearer" or not given:
            raise Unauthorized(
                "This robot needs a token: send 'Authorization: Bearer <token>' "
                "(robotctl: --token or ROBOT_TOKEN)."
            )
        if not hmac.compare_digest(given.strip().encode("utf-8"), expected):
            raise Unauthorized("Wrong token. The robot's token is in its FLASK_MOVE_SERVER_TOKEN environment "
                               "(/etc/flask-move-server/token.env after scripts/install), or server.token / "
                               "server.token_file in its config.")
        return None
