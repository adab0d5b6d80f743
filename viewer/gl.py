"""OpenGL below moderngl: the version and limits the viewer checks, the entry points moderngl does
not wrap (through ctypes), their enums, and the error checks after the calls that upload or allocate.

moderngl (5.x) has no cube-map arrays, no immutable texture storage, no image binding of a texture it
did not make, no framebuffers on array layers, no clip distances and no occlusion queries whose
result can be polled without waiting; `GL(ctx)` reaches those through the context's own function
pointers (`gl_functions`, EGL's or GLX's loader). GL reports a failed call only through
glGetError, so the calls that upload data or allocate memory run inside `GL.checked`, which turns
an error into a GlintError that names what was being done: an allocation that failed silently
would leave an empty texture and black pixels.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import weakref
from contextlib import contextmanager

import moderngl
import numpy as np

from glint.core.errors import GlintError

GL_REQUIRED = 430  # compute shaders and shader storage buffers (DESIGN.md "Viewer")
SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swrast")  # substrings of Mesa's CPU renderers' GL_RENDERER

# -- enums (glcorearb.h) ------------------------------------------------------------------------------
GL_NO_ERROR = 0
GL_ERRORS = {0x0500: "GL_INVALID_ENUM", 0x0501: "GL_INVALID_VALUE", 0x0502: "GL_INVALID_OPERATION",
             0x0503: "GL_STACK_OVERFLOW", 0x0504: "GL_STACK_UNDERFLOW", 0x0505: "GL_OUT_OF_MEMORY",
             0x0506: "GL_INVALID_FRAMEBUFFER_OPERATION"}
GL_OUT_OF_MEMORY = 0x0505
GL_TEXTURE0 = 0x84C0
GL_TEXTURE_CUBE_MAP_ARRAY = 0x9009
GL_TEXTURE_CUBE_MAP_SEAMLESS = 0x884F
GL_TEXTURE_MIN_FILTER, GL_TEXTURE_MAG_FILTER = 0x2801, 0x2800
GL_TEXTURE_WRAP_S, GL_TEXTURE_WRAP_T, GL_TEXTURE_WRAP_R = 0x2802, 0x2803, 0x8072
GL_TEXTURE_BASE_LEVEL, GL_TEXTURE_MAX_LEVEL = 0x813C, 0x813D
GL_LINEAR, GL_LINEAR_MIPMAP_LINEAR, GL_CLAMP_TO_EDGE = 0x2601, 0x2703, 0x812F
GL_RGBA, GL_RGBA16F, GL_RGBA32F = 0x1908, 0x881A, 0x8814
GL_HALF_FLOAT, GL_FLOAT = 0x140B, 0x1406
GL_READ_ONLY, GL_WRITE_ONLY = 0x88B8, 0x88B9
GL_UNPACK_ALIGNMENT, GL_PACK_ALIGNMENT = 0x0CF5, 0x0D05
GL_PIXEL_UNPACK_BUFFER, GL_PIXEL_UNPACK_BUFFER_BINDING = 0x88EC, 0x88EF
GL_PIXEL_PACK_BUFFER, GL_PIXEL_PACK_BUFFER_BINDING = 0x88EB, 0x88ED
GL_FRAMEBUFFER, GL_RENDERBUFFER, GL_FRAMEBUFFER_COMPLETE = 0x8D40, 0x8D41, 0x8CD5
GL_COLOR_ATTACHMENT0, GL_DEPTH_ATTACHMENT = 0x8CE0, 0x8D00
GL_COLOR, GL_DEPTH = 0x1800, 0x1801
GL_CLIP_DISTANCE0 = 0x3000
GL_SCISSOR_TEST = 0x0C11
GL_ANY_SAMPLES_PASSED_CONSERVATIVE = 0x8D6A
# glDrawElementsIndirect's command: count, instanceCount, firstIndex, baseVertex, baseInstance (5 x uint32)
DRAW_ELEMENTS_INDIRECT_COMMAND_BYTES = 20
GL_QUERY_RESULT, GL_QUERY_RESULT_AVAILABLE = 0x8866, 0x8867
GL_TIME_ELAPSED = 0x88BF
GL_TRIANGLES, GL_UNSIGNED_INT = 0x0004, 0x1405
GL_DRAW_INDIRECT_BUFFER, GL_PARAMETER_BUFFER = 0x8F3F, 0x80EE

# The sampling state of every cube-map array: trilinear, and clamped at the face edges (where
# GL_TEXTURE_CUBE_MAP_SEAMLESS filters across them instead).
CUBE_ARRAY_PARAMETERS = ((GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR), (GL_TEXTURE_MAG_FILTER, GL_LINEAR),
                         (GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE), (GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE),
                         (GL_TEXTURE_WRAP_R, GL_CLAMP_TO_EDGE))


# -- version and limits ---------------------------------------------------------------------------------
def check_context(ctx: moderngl.Context, require: int = GL_REQUIRED) -> None:
    """GlintError unless `ctx` offers OpenGL `require` (e.g. a window that got an older context)."""
    if ctx.version_code < require:
        raise GlintError(f"OpenGL {ctx.version_code // 100}.{ctx.version_code % 100 // 10} "
                         f"({describe(ctx)}) is too old: glint needs OpenGL "
                         f"{require // 100}.{require % 100 // 10} for its compute shaders")


def describe(ctx: moderngl.Context) -> str:
    """'renderer (vendor, GL version)', for statistics and messages."""
    info = ctx.info
    return f"{info.get('GL_RENDERER', '?')} ({info.get('GL_VENDOR', '?')}, GL {info.get('GL_VERSION', '?')})"


_PARKED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()  # context -> its 1 x 1 framebuffer


def release_framebuffer(ctx: moderngl.Context, fbo: moderngl.Framebuffer | None) -> None:
    """Release a moderngl framebuffer, binding a 1 x 1 one kept for the purpose first where `fbo` is
    the bound one: moderngl rebinds its last bound framebuffer after it makes a new one, and binding a
    deleted name fails (GL_INVALID_OPERATION, which no later check would tie to its cause)."""
    if fbo is None:
        return
    if ctx.fbo is fbo:
        parked = _PARKED.get(ctx)
        if parked is None:  # made while `fbo` still exists, so moderngl's rebinding succeeds
            # with a depth buffer: moderngl's use() sets glDepthMask from it, and clears after it obey the mask
            parked = _PARKED[ctx] = ctx.framebuffer(ctx.renderbuffer((1, 1)), ctx.depth_renderbuffer((1, 1)))
        parked.use()
    fbo.release()


def software_renderer(ctx: moderngl.Context) -> bool:
    """Whether `ctx` renders on the CPU (Mesa's llvmpipe and its kin)."""
    renderer = ctx.info.get("GL_RENDERER", "").lower()
    return any(name in renderer for name in SOFTWARE_RENDERERS)


def max_texture_size(ctx: moderngl.Context) -> int:
    """Texels per side of the largest 2-D texture (and render target) `ctx` allows."""
    return int(ctx.info.get("GL_MAX_TEXTURE_SIZE", 16384))


def check_texture_size(ctx: moderngl.Context, width: int, height: int, what: str, layers: int = 1,
                       fix: str = "") -> None:
    """GlintError unless `ctx` can hold a texture of width x height (x layers, an array); `what`
    names it and `fix` says what to do, for the message. Past the limits GL refuses the upload
    (GL_INVALID_VALUE), which would leave the texture empty: black or missing surfaces."""
    limit = max_texture_size(ctx)
    max_layers = int(ctx.info.get("GL_MAX_ARRAY_TEXTURE_LAYERS", 2048))
    if width > limit or height > limit or layers > max_layers:
        size = f"{width}x{height}" + (f", {layers} layers" if layers > 1 else "")
        raise GlintError(f"{what} is {size}: more than this OpenGL ({describe(ctx)}) allows ({limit} texels a "
                         f"side, {max_layers} layers)" + (f"; {fix}" if fix else ""))


def check_compute_texture_units(ctx: moderngl.Context, needed: int, why: str) -> None:
    """GlintError unless a compute program of `ctx` can read `needed` texture units (0 .. needed - 1);
    `why` says what needs them, for the message."""
    info = ctx.info
    limit = min(int(info.get("GL_MAX_COMPUTE_TEXTURE_IMAGE_UNITS", 16)),
                int(info.get("GL_MAX_COMBINED_TEXTURE_IMAGE_UNITS", 16)))
    if needed > limit:
        raise GlintError(f"{why} needs {needed} texture units in one compute shader; this OpenGL "
                         f"({describe(ctx)}) offers {limit}")


# -- entry points moderngl does not wrap ------------------------------------------------------------------
def gl_functions(ctx: moderngl.Context):
    """fn(name, restype, *argtypes) -> a ctypes function for a GL entry point moderngl does not
    wrap, from the context's own loader (EGL or GLX)."""
    loader = getattr(getattr(ctx.mglo, "_context", None), "load_opengl_function", None)
    if loader is None:  # a context moderngl did not create through glcontext
        lib = ctypes.CDLL(ctypes.util.find_library("GL") or "libGL.so.1")
        loader = lambda name: ctypes.cast(getattr(lib, name), ctypes.c_void_p).value  # noqa: E731

    def fn(name, restype, *args):
        address = loader(name)
        if not address:
            raise GlintError(f"OpenGL function {name} is missing; glint needs OpenGL 4.3")
        return ctypes.CFUNCTYPE(restype, *args)(address)

    return fn


class GL:
    """The entry points the viewer calls through ctypes, and the few sequences it makes of them."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        fn = gl_functions(ctx)
        u, i, p, b = ctypes.c_uint, ctypes.c_int, ctypes.c_void_p, ctypes.c_ubyte
        pu = ctypes.POINTER(u)
        self.GetError = fn("glGetError", u)
        self.GetIntegerv = fn("glGetIntegerv", None, u, ctypes.POINTER(i))
        self.Enable = fn("glEnable", None, u)
        self.Disable = fn("glDisable", None, u)
        self.ColorMask = fn("glColorMask", None, b, b, b, b)
        self.DepthMask = fn("glDepthMask", None, b)
        self.PixelStorei = fn("glPixelStorei", None, u, i)
        self.BindBuffer = fn("glBindBuffer", None, u, u)
        # textures
        self.GenTextures = fn("glGenTextures", None, i, pu)
        self.DeleteTextures = fn("glDeleteTextures", None, i, pu)
        self.BindTexture = fn("glBindTexture", None, u, u)
        self.ActiveTexture = fn("glActiveTexture", None, u)
        self.TexStorage3D = fn("glTexStorage3D", None, u, i, u, i, i, i)
        self.TexSubImage3D = fn("glTexSubImage3D", None, u, i, i, i, i, i, i, i, u, u, p)
        self.TexParameteri = fn("glTexParameteri", None, u, u, i)
        self.GetTexImage = fn("glGetTexImage", None, u, i, u, u, p)
        self.BindImageTexture = fn("glBindImageTexture", None, u, u, i, b, i, u, u)
        # framebuffers on array layers
        self.GenFramebuffers = fn("glGenFramebuffers", None, i, pu)
        self.DeleteFramebuffers = fn("glDeleteFramebuffers", None, i, pu)
        self.BindFramebuffer = fn("glBindFramebuffer", None, u, u)
        self.FramebufferTextureLayer = fn("glFramebufferTextureLayer", None, u, u, u, i, i)
        self.FramebufferRenderbuffer = fn("glFramebufferRenderbuffer", None, u, u, u, u)
        self.FramebufferTexture = fn("glFramebufferTexture", None, u, u, u, i)
        self.Viewport = fn("glViewport", None, i, i, i, i)
        self.Scissor = fn("glScissor", None, i, i, i, i)
        self.CheckFramebufferStatus = fn("glCheckFramebufferStatus", u, u)
        self.DrawBuffers = fn("glDrawBuffers", None, i, pu)
        self.ClearBufferfv = fn("glClearBufferfv", None, u, i, ctypes.POINTER(ctypes.c_float))
        # occlusion queries
        self.GenQueries = fn("glGenQueries", None, i, pu)
        self.DeleteQueries = fn("glDeleteQueries", None, i, pu)
        self.BeginQuery = fn("glBeginQuery", None, u, u)
        self.EndQuery = fn("glEndQuery", None, u)
        self.GetQueryObjectuiv = fn("glGetQueryObjectuiv", None, u, u, pu)
        self.GetQueryObjectui64v = fn("glGetQueryObjectui64v", None, u, u, ctypes.POINTER(ctypes.c_uint64))
        # draws whose count a buffer holds (GL 4.6, or ARB_indirect_parameters before it); None without
        self.UseProgram = fn("glUseProgram", None, u)
        self.BindVertexArray = fn("glBindVertexArray", None, u)
        self.MultiDrawElementsIndirectCount = None
        if ctx.version_code >= 460 or "GL_ARB_indirect_parameters" in ctx.extensions:
            for name in ("glMultiDrawElementsIndirectCount", "glMultiDrawElementsIndirectCountARB"):
                try:
                    self.MultiDrawElementsIndirectCount = fn(name, None, u, u, p, ctypes.c_ssize_t, i, i)
                    break
                except GlintError:
                    continue

    # -- errors -------------------------------------------------------------------------------------
    def errors(self) -> list[int]:
        """The error flags GL has set since they were last read (which clears them)."""
        found = []
        for _ in range(16):  # a driver may keep several flags; a lost context keeps reporting one
            error = self.GetError()
            if error == GL_NO_ERROR:
                break
            found.append(int(error))
        return found

    @contextmanager
    def checked(self, what: str):
        """`with gl.checked("allocate ..."):` GlintError when a GL call inside the block fails. Flags
        set before the block are cleared unreported: they belong to earlier calls, not to `what`."""
        self.errors()
        yield
        found = self.errors()
        if found:
            names = ", ".join(GL_ERRORS.get(e, f"0x{e:04x}") for e in found)
            hint = ("; the GPU is out of memory: close other programs, or render smaller"
                    if GL_OUT_OF_MEMORY in found else "")
            raise GlintError(f"OpenGL could not {what} ({names}){hint}")

    # -- drawing ------------------------------------------------------------------------------------
    def multi_draw_indirect_count(self, program: moderngl.Program, vao: moderngl.VertexArray,
                                  commands: moderngl.Buffer, first: int, counts: moderngl.Buffer,
                                  count_offset: int, max_draws: int) -> None:
        """What moderngl's `render_indirect` does (program, vertex array, indirect buffer, one
        glMultiDrawElementsIndirect of 32-bit indices), with the number of draws read by the GPU
        from `counts` at byte `count_offset` (at most `max_draws`) instead of given by the CPU:
        commands from command `first` of `commands` (tightly packed, 20 bytes each). Leaves the
        vertex array and the parameter buffer unbound, as moderngl expects to find them."""
        self.UseProgram(program.glo)
        self.BindVertexArray(vao.glo)
        self.BindBuffer(GL_DRAW_INDIRECT_BUFFER, commands.glo)
        self.BindBuffer(GL_PARAMETER_BUFFER, counts.glo)
        self.MultiDrawElementsIndirectCount(GL_TRIANGLES, GL_UNSIGNED_INT, ctypes.c_void_p(first * DRAW_ELEMENTS_INDIRECT_COMMAND_BYTES),
                                            count_offset, max_draws, 0)
        self.BindBuffer(GL_PARAMETER_BUFFER, 0)
        self.BindVertexArray(0)

    # -- textures -----------------------------------------------------------------------------------
    def new_texture(self, target: int) -> int:
        """A new texture name, bound to `target` on moderngl's own scratch unit."""
        name = ctypes.c_uint(0)
        self.GenTextures(1, ctypes.byref(name))
        self.ActiveTexture(GL_TEXTURE0 + self.ctx.default_texture_unit)
        self.BindTexture(target, name.value)
        return name.value

    def delete_textures(self, names) -> None:
        for name in names:
            if name:
                self.DeleteTextures(1, ctypes.byref(ctypes.c_uint(name)))

    @contextmanager
    def _new_cube_array(self, what: str):
        """`with gl._new_cube_array("upload ...") as name:` a new cube-map array, bound on moderngl's
        scratch unit inside the block and unbound after it; deleted again when a call inside fails."""
        name = 0
        try:
            with self.checked(what):
                name = self.new_texture(GL_TEXTURE_CUBE_MAP_ARRAY)
                yield name
        except GlintError:
            self.delete_textures([name])
            raise
        finally:
            self.BindTexture(GL_TEXTURE_CUBE_MAP_ARRAY, 0)

    @contextmanager
    def _from_client_memory(self):
        """`with gl._from_client_memory():` texel uploads inside read their pixels from client memory
        (no pixel-unpack buffer bound, rows byte-aligned); the buffer bound before is bound again."""
        unpack = ctypes.c_int(0)
        self.GetIntegerv(GL_PIXEL_UNPACK_BUFFER_BINDING, ctypes.byref(unpack))
        self.BindBuffer(GL_PIXEL_UNPACK_BUFFER, 0)
        self.PixelStorei(GL_UNPACK_ALIGNMENT, 1)
        try:
            yield
        finally:
            self.BindBuffer(GL_PIXEL_UNPACK_BUFFER, unpack.value)

    def write_cube_layers(self, name: int, level: int, first: int, pixels: np.ndarray, what: str) -> None:
        """Write `pixels`, (n, s, s, 4) float16 or float32 layer-faces (rows from t = 0), into level
        `level` of cube-map array `name` from layer-face `first` on (glTexSubImage3D); the array's
        format stays what it is (GL converts float32 to a half-float array's texels)."""
        pixels = np.ascontiguousarray(pixels)
        count, size = pixels.shape[0], pixels.shape[1]
        half = pixels.dtype == np.float16
        try:
            with self._from_client_memory(), self.checked(f"write {what}"):
                self.ActiveTexture(GL_TEXTURE0 + self.ctx.default_texture_unit)
                self.BindTexture(GL_TEXTURE_CUBE_MAP_ARRAY, name)
                self.TexSubImage3D(GL_TEXTURE_CUBE_MAP_ARRAY, level, 0, 0, first, size, size, count, GL_RGBA,
                                   GL_HALF_FLOAT if half else GL_FLOAT, pixels.ctypes.data)
        finally:
            self.BindTexture(GL_TEXTURE_CUBE_MAP_ARRAY, 0)

    def allocate_cube_array(self, size: int, depth: int, levels: int, internal: int, what: str) -> int:
        """A new immutable cube-map array of `levels` levels, faces of `size` texels, `depth`
        layer-faces (layers x 6), format `internal`, contents undefined; CUBE_ARRAY_PARAMETERS."""
        with self._new_cube_array(f"allocate {what}") as name:
            self.TexStorage3D(GL_TEXTURE_CUBE_MAP_ARRAY, levels, internal, size, size, depth)
            self._cube_array_parameters(levels)
        return name

    def bind_cube_array_image(self, unit: int, name: int, level: int, internal: int, write: bool) -> None:
        """Level `level` of cube-map array `name`, every layer-face (layered), on image unit `unit`,
        read-only or write-only, as `internal` (GL_RGBA16F or GL_RGBA32F: the array's own format)."""
        self.BindImageTexture(unit, name, level, 1, 0, GL_WRITE_ONLY if write else GL_READ_ONLY, internal)

    def _cube_array_parameters(self, levels: int) -> None:
        """CUBE_ARRAY_PARAMETERS and the level range 0 .. levels - 1 on the bound cube-map array."""
        for key, value in (*CUBE_ARRAY_PARAMETERS, (GL_TEXTURE_BASE_LEVEL, 0), (GL_TEXTURE_MAX_LEVEL, levels - 1)):
            self.TexParameteri(GL_TEXTURE_CUBE_MAP_ARRAY, key, value)

    def bind_cube_arrays(self, first_unit: int, names) -> None:
        """Cube-map array k of `names` on texture unit first_unit + k."""
        for k, name in enumerate(names):
            self.ActiveTexture(GL_TEXTURE0 + first_unit + k)
            self.BindTexture(GL_TEXTURE_CUBE_MAP_ARRAY, name)
        self.ActiveTexture(GL_TEXTURE0 + self.ctx.default_texture_unit)  # where moderngl expects it

    def read_cube_array(self, name: int, level: int, out: np.ndarray, what: str) -> np.ndarray:
        """Level `level` of cube-map array `name` into `out`, a C-contiguous float32 array of its
        (layers, 6, s, s, 4) texels, as RGBA float."""
        if out.dtype != np.float32 or not out.flags.c_contiguous:  # GL writes its bytes, whatever `out` is
            raise ValueError("read_cube_array needs a C-contiguous float32 array")
        with self.checked(f"read {what}"):
            pack = ctypes.c_int(0)
            self.GetIntegerv(GL_PIXEL_PACK_BUFFER_BINDING, ctypes.byref(pack))
            self.BindBuffer(GL_PIXEL_PACK_BUFFER, 0)
            self.PixelStorei(GL_PACK_ALIGNMENT, 1)
            self.ActiveTexture(GL_TEXTURE0 + self.ctx.default_texture_unit)
            self.BindTexture(GL_TEXTURE_CUBE_MAP_ARRAY, name)
            self.GetTexImage(GL_TEXTURE_CUBE_MAP_ARRAY, level, GL_RGBA, GL_FLOAT, out.ctypes.data)
            self.BindTexture(GL_TEXTURE_CUBE_MAP_ARRAY, 0)
            self.BindBuffer(GL_PIXEL_PACK_BUFFER, pack.value)
        return out
