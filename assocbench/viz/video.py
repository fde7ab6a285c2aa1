"""Write a run as a video: MP4 (H.264, which browsers play) through imageio-ffmpeg (the ``video``
extra), GIF through Pillow."""

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
    """Refuse a video path that is a folder or names neither an MP4 nor a GIF, and an MP4 where
    its encoder is not installed (``mp4_encoder``)."""
    path = Path(path)
    if path.suffix.lower() not in FORMATS:
        raise UserError(f"video output must end in {' or '.join(FORMATS)}, got {path.name!r}")
    if path.is_dir():
        raise UserError(f"-o {path} is a folder: give a file name such as {path / ('run' + path.suffix)}")
    if path.suffix.lower() == ".mp4":
        mp4_encoder()


def mp4_encoder():
    """The ``imageio_ffmpeg`` module (ffmpeg with libx264), or a one-line error naming the extra."""
    try:
        import imageio_ffmpeg
    except ImportError:
        raise UserError("an .mp4 (H.264) needs the video extra: pip install 'assocbench[video]'; "
                        "or write a .gif") from None
    return imageio_ffmpeg


def check_fps(fps: float) -> float:
    """Refuse a frame rate that is not a finite number in (0, 100] frames per second."""
    if not (math.isfinite(fps) and 0 < fps <= MAX_FPS):
        raise UserError(f"--fps must be a number of frames per second in (0, {MAX_FPS:g}], got {fps:g}")
    return float(fps)


def write_video(path: Path, frames: Iterable[np.ndarray], fps: float = 8.0) -> int:
    """Write RGB frames (H, W, 3) uint8 to ``path`` atomically; return the number written."""
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
        return write_mp4(tmp, frames, fps)


def write_mp4(path: Path, frames: Iterable[np.ndarray], fps: float) -> int:
    """H.264 (libx264, yuv420p for browsers; CRF 18, near lossless for drawings), ``+faststart`` so
    a page plays it while loading; odd sizes repeat an edge row or column."""
    ffmpeg = mp4_encoder()
    writer, count = None, 0
    try:
        for frame in frames:
            if writer is None:
                h, w = frame.shape[:2]
                writer = ffmpeg.write_frames(str(path), (w + w % 2, h + h % 2), fps=float(fps), codec="libx264",
                                             quality=None, macro_block_size=1,
                                             output_params=["-crf", "18", "-movflags", "+faststart"])
                writer.send(None)   # starts ffmpeg
            h, w = frame.shape[:2]
            writer.send(np.ascontiguousarray(np.pad(frame, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge")))
            count += 1
    finally:
        if writer is not None:
            writer.close()
    if not count:
        raise UserError("no frames to write")
    return count
