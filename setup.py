"""flask-move-server: send a ROS 1 robot to named places over HTTP.

rospy, actionlib, tf2 and the message packages come from the system (Debian's
python3-rospy & co., or /opt/ros/noetic), not from PyPI: install into a venv
made with --system-site-packages (``make setup`` does).
"""

import re
from pathlib import Path

from setuptools import find_packages, setup

HERE = Path(__file__).parent
VERSION = re.search(r'__version__ = "([^"]+)"', (HERE / "flask_move_server" / "__init__.py").read_text()).group(1)

setup(
    name="flask-move-server",
    version=VERSION,
    description="Send a Raspberry Pi ROS 1 robot to named waypoints with one HTTP request",
    long_description=(HERE / "README.md").read_text(encoding="utf-8"),
    long_description_content_type="text/markdown",
    license="BSD-3-Clause",
    python_requires=">=3.8",
    packages=find_packages(include=["flask_move_server", "flask_move_server.*"]),
    include_package_data=True,
    package_data={"flask_move_server": ["web/static/*", "web/static/js/*"]},
    # The demo map and the documented config, where `--sim` looks for them outside a checkout.
    data_files=[
        ("share/flask_move_server/config/maps", ["config/maps/demo.yaml", "config/maps/demo.pgm"]),
        ("share/flask_move_server/config", ["config/robot.yaml", "config/waypoints.demo.yaml"]),
    ],
    install_requires=[
        "Flask>=2.2",
        "waitress>=2.1",
        "PyYAML>=5.3",
        "requests>=2.22",
        "zeroconf>=0.47",
        "ifaddr>=0.1.7",  # zeroconf's own dependency; lan/mdns.py polls the interfaces with it
        "pyserial>=3.4",
        "numpy>=1.17",  # explore/: frontiers and reachability, vectorised (Debian's python3-numpy; 1.17 on Noetic)
        # mqtt/ and vda5050/: Home Assistant and fleet managers (off by default). Debian bookworm's 1.6.1
        # and PyPI's 2.x (mqtt/paho_compat.py bridges their callback APIs).
        "paho-mqtt>=1.5",
    ],
    extras_require={
        "test": ["pytest>=7", "pytest-timeout>=2", "pytest-xdist>=2.5", "hypothesis>=6", "ruff>=0.4", "vermin>=1.5",
                 # The API fuzz run (tests/test_openapi_fuzz.py), written for both: pip takes 4.x where the
                 # Python has one (3.9+; the newest need 3.11), 3.x on 3.8.
                 "schemathesis>=3.27,<5",
                 # The phone page's browser tests (tests/test_page_*.py) drive Debian's chromium with it;
                 # the pip package brings its driver, never a browser (`playwright install` is not run).
                 "playwright>=1.40",
                 # The VDA 5050 tests check every message against the standard's JSON schemas, as this package
                 # bundles them (2.1.0, which 2.0.0 messages meet); it needs Python 3.10+.
                 "vda5050-sdk==0.2.0; python_version >= '3.10'"],
        "pi": ["RPi.GPIO>=0.7; platform_machine in 'armv7l aarch64'"],
    },
    entry_points={
        "console_scripts": [
            "flask-move-server = flask_move_server.app.cli:main",
            "robotctl = flask_move_server.robotctl.cli:main",
            "flask-move-base = flask_move_server.drive.__main__:main",
            "record-waypoints = flask_move_server.recorder:main",
        ],
    },
    classifiers=[
        "License :: OSI Approved :: BSD License",
        "Programming Language :: Python :: 3.8",
        "Programming Language :: Python :: 3.11",
        "Framework :: Flask",
        "Topic :: Scientific/Engineering :: Artificial Intelligence",
    ],
)
