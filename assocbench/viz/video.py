"""Write a run as a video: MP4 through OpenCV, GIF through Pillow (matplotlib's dependency)."""

from __future__ import annotations

import math
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from ..atomic import OUTPUT_FILE, atomic_path
from ..errors import UserError

FORMATS = (".mp4", ".gif")
MAX_FPS = 100.0   # a GIF frame lasts a whole number of centiseconds: 100 fps is its limit


def check_video_path(path: Path) -> None:
    """Refuse a video path that is a folder or names neither an MP4 nor a GIF."""
    path = Path(path)
    if path.suffix.lower() not in FORMATS:
        raise UserError(f"video output must end in {' or '.join(FORMATS)}, got {path.name!r}")
    if path.is_dir():
        raise UserError(f"-o {path} is a folder: give a file name such as {path / ('run' + path.suffix)}")


def check_fps(fps: float) -> float:
    """Refuse a frame rate that is not a finite number in (0, 100] frames per second."""
    if not (math.isfinite(fps) and 0 < fps <= MAX_FPS):
        raise UserError(f"--fps must be a number of frames per second in (0, {MAX_FPS:g}], got {fps:g}")
    return float(fps)


def write_video(path: Path, frames: Iterable[np.ndarray], fps: float = 8.0) -> int:
    """Write RGB frames (H, W, 3) uint8 to ``path`` atomically; return the number written."""
    import cv2

    path = Path(path)
    check_video_path(path)
    check_fps(fps)
    with atomic_path(path, role=OUTPUT_FILE) as tmp:
        if path.suffix.lower() == ".gif":
            from PIL import Image

            # octree quantisation keeps a colour that covers a few pixels (a key's swatch), which
            # PIL's default median cut merged into its neighbours (a red swatch drawn brown)
            images = [Image.fromarray(f).quantize(256, method=Image.Quantize.FASTOCTREE) for f in frames]
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
