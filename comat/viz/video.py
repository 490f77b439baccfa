"""Videos of episodes: frames of :mod:`comat.envs.render` encoded to ``.mp4`` or ``.gif``, headless.

``.mp4``: H.264 (yuv420p, what browsers and slide software play) through imageio's ffmpeg
plugin, whose ``imageio-ffmpeg`` wheel ships an ffmpeg binary (no system install). ``.gif``:
Pillow, each frame on its own 64-colour palette. Either way the file is written under a hidden
temporary name next to its target and renamed into place when complete: a failed or
interrupted rollout leaves no half-written video.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path
from typing import Self

import numpy as np

__all__ = ["VIDEO_SUFFIXES", "VideoWriter", "check_video_path"]

VIDEO_SUFFIXES = (".mp4", ".gif")


def check_video_path(path: str | Path) -> Path:
    """``path`` as a Path if it names a ``.mp4`` or ``.gif`` file (ValueError otherwise)."""
    p = Path(path)
    if p.suffix.lower() not in VIDEO_SUFFIXES:
        raise ValueError(f"video must be a file name ending in .mp4 or .gif, got {str(p)!r}")
    if p.is_dir():
        raise ValueError(f"video must be a file, got {str(p)!r}, which is a folder")
    return p


class VideoWriter:
    """Appends (H, W, 3) uint8 frames to a video file; a context manager.

    Args:
        path: ``.mp4`` or ``.gif`` file; its folder must exist.
        fps: frames per second (>= 1).

    ``close()`` finishes the file and renames it into place; leaving the ``with`` block by an
    exception removes the temporary file instead.
    """

    def __init__(self, path: str | Path, fps: int = 10) -> None:
        self.path = check_video_path(path)
        if isinstance(fps, bool) or not isinstance(fps, int) or fps < 1:
            raise ValueError(f"fps must be a positive integer, got {fps!r}")
        if not self.path.parent.is_dir():
            raise ValueError(f"video: folder {str(self.path.parent)!r} does not exist, got {str(self.path)!r}")
        self.fps = fps
        self.frames = 0
        self.size: tuple[int, int] | None = None
        # The suffix stays last: ffmpeg picks the container from it.
        self._tmp = self.path.with_name(f".{self.path.stem}.{os.getpid()}.tmp{self.path.suffix}")
        self._gif: list = []
        self._mp4 = None
        if self.path.suffix.lower() == ".mp4":
            import imageio.v2 as imageio

            self._mp4 = imageio.get_writer(
                self._tmp,
                format="FFMPEG",
                mode="I",
                fps=fps,
                codec="libx264",
                pixelformat="yuv420p",
                quality=7,
                macro_block_size=16,
                ffmpeg_log_level="error",
            )

    def append(self, frame: np.ndarray) -> None:
        """Add one frame (H, W, 3) uint8; every frame of a video has the first one's size."""
        frame = np.asarray(frame)
        if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
            raise ValueError(f"frame must be an (H, W, 3) uint8 array, got {frame.shape} {frame.dtype}")
        if self.size is None:
            self.size = frame.shape[:2]
        elif frame.shape[:2] != self.size:
            raise ValueError(f"frame must be {self.size} like the first one, got {frame.shape[:2]}")
        if self._mp4 is not None:
            self._mp4.append_data(frame)
        else:
            from PIL import Image

            # Quantized now, so a long GIF holds palette images (1 byte per pixel), not RGB arrays.
            self._gif.append(Image.fromarray(frame).quantize(colors=64, method=Image.Quantize.MEDIANCUT))
        self.frames += 1

    def close(self) -> Path:
        """Finish the file and move it to ``path``; returns ``path``."""
        if self.frames == 0:
            self.abort()
            raise ValueError(f"video {str(self.path)!r}: no frames to write")
        if self._mp4 is not None:
            self._mp4.close()
        else:
            first, *rest = self._gif
            first.save(
                self._tmp, format="GIF", save_all=True, append_images=rest, duration=round(1000 / self.fps), loop=0
            )
        os.replace(self._tmp, self.path)
        return self.path

    def abort(self) -> None:
        """Drop the unfinished file."""
        if self._mp4 is not None:
            # An encoder that already failed may fail again on close: the file goes either way.
            with contextlib.suppress(Exception):
                self._mp4.close()
        self._tmp.unlink(missing_ok=True)

    def __enter__(self) -> Self:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()
