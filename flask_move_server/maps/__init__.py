"""Maps, pure: the maps folder (:mod:`.catalogue`), map_saver's file pair (:mod:`.mapfile`) and
occupancy grids as cropped PNG images (:mod:`.render`). No rospy, no Flask."""
