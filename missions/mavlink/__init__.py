"""The ground side of MAVLink: what a ground station does with our missions and vehicles.

One module per protocol concept: :mod:`.transport` (connection strings, one reader thread
a link), :mod:`.policy` (the stated timeouts and retries), :mod:`.messages` (messages as
plain data), :mod:`.transfer` (mission upload, download, clear), :mod:`.upload` (upload
with read-back verification), :mod:`.params` (parameters), :mod:`.commands` (streams,
arming, one common start and release), :mod:`.telemetry`, :mod:`.tlog`, :mod:`.fleet`
(all of it on three vehicles at once) and :mod:`.errors`. The simulated vehicle the tests
fly against is :mod:`missions.mock`.
"""
