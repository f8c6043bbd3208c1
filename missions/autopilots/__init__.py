"""ArduCopter as our missions meet it: what it does with them (:mod:`.ardupilot`, the one
place that says), its spline legs (:mod:`.spline`, :mod:`.chain`) and the speed limits that
time them (:mod:`.speed_solver`)."""
