"""What a costmap's keepout layer hears: ``python -m tests.mask_reader [count]`` prints, for each of the
first ``count`` (default 1) messages on ``keepout_map`` and the one on ``map`` it was made for, a JSON
line ``{"mask": {...}, "map": {...}}``: the header's frame, the info's size, resolution and origin as
sent (the raw bytes, hex), and the indices of the mask's lethal cells."""

import json
import sys
import threading

import rospy

from flask_move_server.zones import TOPIC

INFO_BYTES = 76


def described(raw):
    frame_len = int.from_bytes(raw[12:16], "little")
    head = 16 + frame_len
    data = raw[head + INFO_BYTES + 4:]
    return {"frame": raw[16:head].decode(), "info": raw[head + 8:head + INFO_BYTES].hex(), "cells": len(data),
            "lethal": [i for i, v in enumerate(data) if v == 100], "other": sorted(set(data) - {100})}


def main():
    count = int(sys.argv[1]) if len(sys.argv) > 1 else 1
    rospy.init_node("mask_reader", anonymous=True, disable_signals=True)
    latest_map, done = {}, threading.Event()
    heard = []

    def on_map(msg):
        latest_map["raw"] = msg._buff

    def on_mask(msg):
        heard.append(1)
        print(json.dumps({"mask": described(msg._buff), "map": described(latest_map["raw"]) if latest_map else None}),
              flush=True)
        if len(heard) >= count:
            done.set()
    rospy.Subscriber("map", rospy.AnyMsg, on_map, queue_size=1, buff_size=1 << 22)
    rospy.sleep(0.5)
    rospy.Subscriber(TOPIC, rospy.AnyMsg, on_mask, queue_size=5, buff_size=1 << 22)
    done.wait(60)


if __name__ == "__main__":
    main()
