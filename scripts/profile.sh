# /etc/profile.d/flask-move-server.sh, written by scripts/install: the robot's ROS environment
# in login shells, so `roslaunch flask_move_server ...`, `rostopic ...` and `rosrun map_server
# map_saver` work over ssh as they do in the systemd units. POSIX sh (sourced by /etc/profile).
if [ -r /etc/flask-move-server/ros.env ]; then
    _fms_ros_home=$ROS_HOME
    set -a
    . /etc/flask-move-server/ros.env
    set +a
    # The units' ROS_HOME belongs to user robot: keep yours (default ~/.ros).
    if [ -n "$_fms_ros_home" ]; then ROS_HOME=$_fms_ros_home; else unset ROS_HOME; fi
    unset _fms_ros_home
    if [ -n "$ROS_SETUP" ] && [ -r "${ROS_SETUP%.bash}.sh" ]; then
        . "${ROS_SETUP%.bash}.sh"
    fi
    ROS_PACKAGE_PATH="${FLASK_MOVE_SERVER_SHARE:-/opt/flask-move-server/share}${ROS_PACKAGE_PATH:+:$ROS_PACKAGE_PATH}"
    export ROS_PACKAGE_PATH
fi
