"""The recorded range-bearing track (``planar_log``): Victoria Park or a user's log, scored against
its reference association and a reference solution fitted to it."""
