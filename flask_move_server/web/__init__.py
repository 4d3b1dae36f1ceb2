"""The Flask app: ``create_app(config, robot, store)``.

Shared objects live in ``app.extensions["flask_move_server"]``, never in a
module global, so several apps (tests) can live in one process.
"""

from flask import Blueprint, Flask, send_from_directory

from flask_move_server.web import auth, errors
from flask_move_server.web.estop import estop
from flask_move_server.web.routes import api


def create_app(config, robot, store, token=None):
    """Build the WSGI app serving ``robot`` and the waypoints in ``store``."""
    app = Flask(__name__, static_folder="static", static_url_path="/static")
    app.config["MAX_CONTENT_LENGTH"] = config.server.max_body_bytes
    app.json.sort_keys = False
    app.extensions["flask_move_server"] = {"config": config, "robot": robot, "store": store}
    errors.init_app(app)
    auth.init_app(app, token)
    app.register_blueprint(api)
    app.register_blueprint(estop)
    if config.server.static:
        _add_page(app)
    return app


def _add_page(app):
    page = Blueprint("page", __name__)

    @page.route("/", methods=["GET"])
    def index():
        return send_from_directory(app.static_folder, "index.html")

    app.register_blueprint(page)
