"""Frame sources: what a track reads its frames from, simulated or recorded (``base.FrameSource``)."""
