"""The recorded range-bearing track (``planar_log``): Victoria Park, or a user's own log in the same
format, scored against the log's reference association and a reference solution fitted to it."""
