"""Pictures of a world state: frames drawn with OpenCV (:mod:`~physrover.viz.render`:
:class:`~physrover.viz.render.RenderConfig`, :func:`~physrover.viz.render.draw_frame`) and
H.264 MP4 files (:mod:`~physrover.viz.video`: :class:`~physrover.viz.video.VideoWriter`).
What the envs' ``render_mode="rgb_array"`` and ``physrover render`` draw.

May import: :mod:`physrover.core`, :mod:`physrover.config`, :mod:`physrover.domain`.
"""
