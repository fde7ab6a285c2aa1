"""Write a run as a video: MP4 through OpenCV, GIF through Pillow (matplotlib's dependency)."""

from __future__ import annotations

from pathlib import Path
from typing import Iterable

import numpy as np

from ..atomic import atomic_path
from ..errors import UserError

FORMATS = (".mp4", ".gif")


def check_video_path(path: Path) -> None:
    if path.suffix.lower() not in FORMATS:
        raise UserError(f"video output must end in {' or '.join(FORMATS)}, got {path.name!r}")


def write_video(path: Path, frames: Iterable[np.ndarray], fps: float = 8.0) -> int:
    """Write RGB frames (H, W, 3) uint8 to ``path`` atomically; return the number written."""
    import cv2

    path = Path(path)
    check_video_path(path)
    with atomic_path(path) as tmp:
        if path.suffix.lower() == ".gif":
            from PIL import Image

            images = [Image.fromarray(f) for f in frames]
            if not images:
                raise UserError("no frames to write")
            images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:],
                           duration=int(1000 / fps), loop=0)
            return len(images)
        writer, count = None, 0
        for frame in frames:
            if writer is None:
                h, w = frame.shape[:2]
                writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), fps, (w, h))
                if not writer.isOpened():
                    raise UserError("OpenCV cannot write MP4 here; write a .gif instead")
            writer.write(cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))
            count += 1
        if writer is not None:
            writer.release()
        return count
