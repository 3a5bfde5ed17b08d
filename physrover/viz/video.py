"""Checked H.264 MP4 writing: frames in, a video that plays everywhere or a loud error.

Videos (:class:`VideoWriter`) are H.264 (libx264, yuv420p) MP4 written with PyAV, which
browsers, GitHub and VS Code play; yuv420p needs even frame sizes, which
:class:`~physrover.viz.render.RenderConfig` requires (no hidden padding: a frame is the video's
size). The frames come from :mod:`physrover.viz.render`.
"""

from __future__ import annotations

import os
from fractions import Fraction
from pathlib import Path

import av
import numpy as np

VIDEO_CODEC = "libx264"
VIDEO_OPTIONS = {"crf": "21", "preset": "medium"}
"""x264 quality and speed (CRF 21: clean drawings; about 0.5 Mbit/s, 70 kB a second, for a
1284 x 640 side-by-side video)."""


class VideoError(RuntimeError):
    """The video could not be written completely."""


class VideoWriter:
    """H.264 MP4 writer (PyAV, libx264, yuv420p) that fails loudly instead of leaving an
    empty, short or undecodable file.

    Frames are (height, width, 3) RGB uint8; width and height must be even (yuv420p halves
    the chroma resolution). A frame of another shape or dtype raises before it reaches the
    encoder; an encoding or write failure raises :class:`VideoError` naming the file. On
    close the file is read back: it must hold an H.264 yuv420p stream with exactly the frames
    written. The frames go to a temporary file beside ``path`` (``.NAME.partial``) that
    replaces ``path`` only once it passed that check, so a failure (or an interrupted
    recording) never leaves a broken file in place of a good one. Use as a context manager
    (an exception inside skips the check and removes the temporary file) or call
    :meth:`close`. Quality: :data:`VIDEO_OPTIONS`; ``movflags=+faststart`` puts the index
    first, so browsers start playing before the download ends.
    """

    def __init__(self, path: str | Path, width: int, height: int, fps: int):
        self.path = Path(path)
        # A regular file is written beside and renamed into place; a device or a pipe
        # (/dev/stdout, /dev/full) is written to directly: it cannot be replaced.
        regular = not self.path.exists() or self.path.is_file()
        self._partial = self.path.with_name(f".{self.path.name}.partial") if regular else self.path
        self.size = (width, height)
        self.frames = 0
        self._container = self._stream = None
        if width % 2 or height % 2 or width < 2 or height < 2:
            raise VideoError(
                f"cannot write {self.path}: H.264 yuv420p needs an even width and height, "
                f"got {width}x{height}"
            )
        if not self.path.parent.is_dir():
            raise VideoError(f"cannot write {self.path}: no directory {self.path.parent}")
        if self.path.is_dir():
            raise VideoError(f"cannot open {self.path} for writing (H.264): it is a directory")
        try:
            self._partial.open("wb").close()  # PyAV opens the file only at the first packet
            self._container = av.open(
                str(self._partial), "w", format="mp4", options={"movflags": "+faststart"}
            )
            self._stream = self._container.add_stream(VIDEO_CODEC, rate=Fraction(fps))
            self._stream.width, self._stream.height = width, height
            self._stream.pix_fmt = "yuv420p"
            self._stream.options = dict(VIDEO_OPTIONS)
        except (av.FFmpegError, OSError, ValueError) as exc:
            self.close(check=False)
            raise VideoError(f"cannot open {self.path} for writing (H.264): {exc}") from exc

    def write(self, frame: np.ndarray) -> None:
        """Encode one (height, width, 3) uint8 RGB frame."""
        if self._container is None:
            raise VideoError(f"{self.path} is closed")
        expected = (self.size[1], self.size[0], 3)
        if frame.shape != expected or frame.dtype != np.uint8:
            self.close(check=False)
            raise VideoError(
                f"frame must be uint8 of shape {expected}, got {frame.dtype} {frame.shape}"
            )
        try:
            video_frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(frame), format="rgb24")
            video_frame.pts = self.frames  # in 1/fps units
            self._mux(video_frame)
        except (av.FFmpegError, OSError, ValueError) as exc:
            self.close(check=False)
            raise VideoError(f"writing frame {self.frames} of {self.path} failed: {exc}") from exc
        self.frames += 1

    def _mux(self, frame) -> None:
        """Encode ``frame`` (None: flush the encoder) and write the packets out."""
        for packet in self._stream.encode(frame):
            self._container.mux(packet)

    def close(self, check: bool = True) -> None:
        """Flush and close the file; with ``check``, read it back (see the class doc) and
        move it into place.

        ``check=False`` (after a failure) closes quietly and removes what was written."""
        if self._container is None:
            return
        error = None
        try:
            if self._stream is not None:
                self._mux(None)
        except (av.FFmpegError, OSError, ValueError) as exc:
            error = exc
        container, self._container = self._container, None
        try:
            container.close()
        except (av.FFmpegError, OSError, ValueError) as exc:
            error = error or exc
        try:
            if not check:
                return
            if error is not None:
                raise VideoError(f"finishing {self.path} failed: {error}") from error
            self._check()
            if self._partial != self.path:
                try:
                    os.replace(self._partial, self.path)
                except OSError as exc:
                    raise VideoError(f"cannot write {self.path}: {exc.strerror}") from exc
        finally:
            if self._partial != self.path:
                self._partial.unlink(missing_ok=True)

    def _check(self) -> None:
        """Read the closed file back: codec, pixel format and frame count."""
        if self.frames == 0:
            raise VideoError(f"{self.path}: no frames were written")
        try:
            with av.open(str(self._partial)) as container:
                stream = container.streams.video[0]
                codec, pix_fmt = stream.codec_context.name, stream.codec_context.pix_fmt
                count = sum(1 for packet in container.demux(stream) if packet.size)
        except (av.FFmpegError, OSError, IndexError) as exc:
            raise VideoError(f"cannot read back {self.path}: {exc}") from exc
        if (codec, pix_fmt) != ("h264", "yuv420p"):
            raise VideoError(f"{self.path} holds {codec} {pix_fmt}, not h264 yuv420p")
        if count != self.frames:
            raise VideoError(f"{self.path} holds {count} frames, {self.frames} were written")

    def __enter__(self) -> VideoWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close(check=exc_type is None)
