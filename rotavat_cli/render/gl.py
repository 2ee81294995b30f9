"""OpenGL rasteriser: moderngl with a headless EGL context (Mesa's llvmpipe on a CPU-only machine).

Contract shared with :func:`rotavat_cli.render.fallback.rasterize_numpy`: points ``(N, 3)``,
triangles ``(F, 3)`` and per-vertex colours go through one ``clip_from_points`` 4x4 matrix
(OpenGL clip space); the result is an ``(H, W, 4)`` float32 image, row 0 at the top, alpha =
coverage (4x multisampled, so edges are anti-aliased).

``moderngl`` is imported inside :func:`open_gl_context` only, which raises :class:`RotavatError`
saying what is missing; choosing a renderer (and falling back) is :mod:`rotavat_cli.render.raster`'s.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import RotavatError

__all__ = ["GLContext", "open_gl_context", "unpremultiply", "GL_SYSTEM_PACKAGES"]

GL_SYSTEM_PACKAGES = "libegl1 libegl-mesa0 libgl1-mesa-dri"  # Debian packages moderngl's EGL backend needs
_SAMPLES = 4  # multisample count (anti-aliasing); 0 if the driver refuses

_VERTEX_SHADER = """
#version 330
uniform mat4 clip_from_points;
in vec3 in_pos;
in vec3 in_color;
out vec3 v_color;
void main() {
    gl_Position = clip_from_points * vec4(in_pos, 1.0);
    v_color = in_color;
}
"""
_FRAGMENT_SHADER = """
#version 330
in vec3 v_color;
out vec4 f_color;
void main() {
    f_color = vec4(v_color, 1.0);
}
"""


class GLContext:
    """A standalone moderngl context with one program and framebuffers resized on demand."""

    def __init__(self, moderngl: Any) -> None:
        self.mgl = moderngl
        self.ctx = moderngl.create_context(standalone=True, backend="egl")
        self.prog = self.ctx.program(vertex_shader=_VERTEX_SHADER, fragment_shader=_FRAGMENT_SHADER)
        self.size: tuple[int, int] | None = None
        self.samples = _SAMPLES
        self.fbos: tuple[Any, Any] | None = None

    def _framebuffers(self, size: tuple[int, int]) -> tuple[Any, Any]:
        """(draw, resolve) framebuffers of ``size``; multisampled draw target when the driver allows."""
        if self.size != size or self.fbos is None:
            for fbo in self.fbos or ():
                fbo.release()
            resolve = self.ctx.framebuffer(color_attachments=[self.ctx.renderbuffer(size, 4)])
            try:
                draw = self.ctx.framebuffer(color_attachments=[self.ctx.renderbuffer(size, 4, samples=self.samples)],
                                            depth_attachment=self.ctx.depth_renderbuffer(size, samples=self.samples))
            except self.mgl.Error:
                self.samples = 0
                draw = self.ctx.framebuffer(color_attachments=[self.ctx.renderbuffer(size, 4)],
                                            depth_attachment=self.ctx.depth_renderbuffer(size))
            self.fbos, self.size = (draw, resolve), size
        return self.fbos

    def rasterize(self, points: np.ndarray, faces: np.ndarray, colors: np.ndarray, clip_from_points: np.ndarray,
                  size: tuple[int, int]) -> np.ndarray:
        """(N, 3) points, (F, 3) faces, (N, 3) colours -> (H, W, 4) float32 RGBA, row 0 at the top."""
        W, H = int(size[0]), int(size[1])
        draw, resolve = self._framebuffers((W, H))
        draw.use()
        self.ctx.enable(self.mgl.DEPTH_TEST)
        self.ctx.disable(self.mgl.CULL_FACE)
        draw.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        faces = np.asarray(faces, dtype=np.uint32).reshape(-1, 3)
        if faces.shape[0] and len(points):
            self.prog["clip_from_points"].write(np.asarray(clip_from_points, dtype="f4").T.tobytes())  # column-major
            vbo = self.ctx.buffer(np.hstack([np.asarray(points, "f4"), np.asarray(colors, "f4")]).tobytes())
            ibo = self.ctx.buffer(faces.tobytes())
            vao = self.ctx.vertex_array(self.prog, [(vbo, "3f 3f", "in_pos", "in_color")], index_buffer=ibo, index_element_size=4)
            vao.render(self.mgl.TRIANGLES)
            for obj in (vao, ibo, vbo):
                obj.release()
        self.ctx.copy_framebuffer(resolve, draw)
        data = np.frombuffer(resolve.read(components=4, dtype="f1"), dtype=np.uint8).reshape(H, W, 4)
        return unpremultiply(data[::-1])  # GL rows run bottom-up

    def release(self) -> None:
        """Free GL objects and the context."""
        for fbo in self.fbos or ():
            fbo.release()
        self.prog.release()
        self.ctx.release()


    @property
    def renderer_name(self) -> str:
        """The driver's GL_RENDERER string (e.g. llvmpipe)."""
        return str(self.ctx.info.get("GL_RENDERER", ""))


def unpremultiply(rgba8: np.ndarray) -> np.ndarray:
    """(H, W, 4) uint8 resolved RGBA (colour premultiplied by coverage) -> (H, W, 4) float32 in [0, 1], colour
    divided by coverage (0 where nothing is drawn).

    Only the edge pixels (0 < alpha < 1) are divided: a covered pixel's colour is itself and an empty one's
    0, so the work follows the silhouettes' length, not the panel's area.

    >>> [round(float(v), 3) for v in unpremultiply(np.array([[[100, 50, 0, 255], [50, 25, 0, 128], [9, 9, 9, 0]]], np.uint8))[0, :, 0]]
    [0.392, 0.391, 0.0]
    """
    rgba = rgba8.astype(np.float32) / 255.0
    alpha = rgba8[..., 3]
    rgba[alpha == 0, :3] = 0.0
    edge = (alpha > 0) & (alpha < 255)
    part = rgba[edge]  # (E, 4)
    part[:, :3] = np.clip(part[:, :3] / np.maximum(part[:, 3:4], 1e-6), 0.0, 1.0)
    rgba[edge] = part
    return rgba


def open_gl_context() -> GLContext:
    """A moderngl/EGL context; raises RotavatError (exit 2) saying what is missing."""
    try:
        import moderngl  # lazy: optional extra rotavat[gl]
    except ImportError as exc:
        raise RotavatError(f"OpenGL renderer unavailable: moderngl is not installed ({exc}); "
                           "pip install 'moderngl>=5.13' or use --renderer fallback") from None
    try:
        return GLContext(moderngl)
    except Exception as exc:  # glcontext raises plain Exception when EGL/Mesa is missing
        raise RotavatError(f"OpenGL renderer unavailable: no EGL context ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__}); "
                           f"install the system packages {GL_SYSTEM_PACKAGES} or use --renderer fallback") from None
