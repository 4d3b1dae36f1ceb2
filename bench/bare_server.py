"""The baseline of bench_server.py: the least a Flask + rospy server can do.

``POST /goto`` publishes a MoveBaseActionGoal with rospy, ``GET /status`` answers a
small JSON. Served by waitress, or with ``--werkzeug`` by werkzeug's development server
(threaded), which is what a bare ``flask run`` gives.
"""

import argparse
import sys

import rospy
from flask import Flask, jsonify, request
from move_base_msgs.msg import MoveBaseActionGoal


def make_app():
    app = Flask(__name__)
    pub = rospy.Publisher("bare/move_base/goal", MoveBaseActionGoal, queue_size=10, tcp_nodelay=True)

    @app.route("/goto", methods=["POST"])
    def goto():
        data = request.get_json(force=True)
        msg = MoveBaseActionGoal()
        msg.goal.target_pose.header.frame_id = "map"
        msg.goal.target_pose.pose.position.x = data["x"]
        msg.goal.target_pose.pose.position.y = data["y"]
        msg.goal.target_pose.pose.orientation.w = 1.0
        pub.publish(msg)
        return jsonify({"status": "ok"}), 202

    @app.route("/status")
    def status():
        return jsonify({"navigation": {"state": "idle"}, "pose": None})

    return app


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--werkzeug", action="store_true")
    opts = parser.parse_args()
    rospy.init_node("bare_server", anonymous=True, disable_signals=True)
    app = make_app()
    if opts.werkzeug:
        from werkzeug.serving import make_server

        server = make_server("127.0.0.1", 0, app, threaded=True)
        print("bare server on http://127.0.0.1:{}".format(server.port), file=sys.stderr, flush=True)
        server.serve_forever()
    else:
        import waitress

        server = waitress.create_server(app, host="127.0.0.1", port=0, threads=6, clear_untrusted_proxy_headers=True)
        print("bare server on http://127.0.0.1:{}".format(server.effective_port), file=sys.stderr, flush=True)
        server.run()


if __name__ == "__main__":
    main()
