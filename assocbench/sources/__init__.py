"""Frame sources: what a track reads its frames from, simulated (a MuJoCo scene along a path) or
recorded (a log file). ``base.FrameSource`` is the interface every track's source implements."""
