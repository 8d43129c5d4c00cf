"""Compile stage: materials and textures. Each material's row of the material table is packed by
its kind's module (kernels/shading/materials/); image textures are decoded to linear float32
RGB (normal, bump and alpha maps kept as stored), mip-mapped, and joined into one texel atlas."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import SceneError
from ..kernels.shading import materials as M
from ..kernels.shading import textures as X
from ..scene.checks import warn
from ..scene.model import AlphaMap, BumpMap, ImageTexture, Material, NormalMap


def srgb_to_linear(x: np.ndarray) -> np.ndarray:
    """The sRGB transfer curve, inverted (x in 0..1)."""
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def _rgb_of(im) -> np.ndarray:
    """An image's colours as float32 (H, W, 3) in 0..1, still sRGB-encoded. 16-bit and 32-bit
    greyscale (Pillow's I;16 and I modes) are scaled from their own range: Pillow's conversion
    to RGB clips them at 255, and a 16-bit grey texture had rendered white. Float greyscale (a
    TIFF's F mode) is read as it is, clipped to 0..1: converted, it was rounded to 0 or 1/255."""
    if im.mode.startswith("I;16") or im.mode == "I":
        grey = np.asarray(im, dtype=np.float64)
        top = 65535.0 if im.mode.startswith("I;16") or grey.max(initial=0) <= 65535 else 4294967295.0
        grey = np.clip(grey / top, 0.0, 1.0).astype(np.float32)
        return np.repeat(grey[..., None], 3, axis=2)
    if im.mode == "F":
        grey = np.clip(np.nan_to_num(np.asarray(im, dtype=np.float32)), 0.0, 1.0)
        return np.repeat(grey[..., None], 3, axis=2)
    return np.asarray(im.convert("RGB"), dtype=np.float32) / np.float32(255.0)


def sixteen_bit_colour_png(path: Path, im) -> bool:
    """Whether `im` is a PNG of 16-bit colour (RGB or RGBA), which Pillow decodes to 8 bits: its
    header's bit depth (byte 24) and colour type (byte 25: 2 RGB, 6 RGBA)."""
    if im.format != "PNG" or im.mode not in ("RGB", "RGBA"):
        return False
    with open(path, "rb") as fh:
        header = fh.read(26)
    return len(header) == 26 and header[24] == 16 and header[25] in (2, 6)


def _coverage_of(im) -> np.ndarray:
    """A mask's coverage as float32 (H, W, 3) in 0..1, the same in each channel: its alpha
    channel (a palette's transparency included), or its grey (the mean of r, g and b) where it
    has no alpha."""
    if "A" in im.getbands() or (im.mode == "P" and "transparency" in im.info):
        a = np.asarray(im.convert("RGBA"), dtype=np.float32)[..., 3] / np.float32(255.0)
    else:
        a = _rgb_of(im).mean(axis=2, dtype=np.float32)
    return np.repeat(a[..., None], 3, axis=2)


def mip_levels(texels: np.ndarray) -> list[np.ndarray]:
    """The image (float32 (H, W, 3)) and its mip-map: each level the area average of the one
    before at half its size (rounded down, at least 1), down to 1 x 1."""
    from PIL import Image as PILImage

    levels = [texels]
    while levels[-1].shape[0] > 1 or levels[-1].shape[1] > 1:
        h, w = levels[-1].shape[:2]
        size = (max(1, w // 2), max(1, h // 2))
        channels = [
            np.asarray(
                PILImage.fromarray(np.ascontiguousarray(levels[-1][:, :, c]), mode="F").resize(size, PILImage.BOX)
            )
            for c in range(3)
        ]
        levels.append(np.stack(channels, axis=-1).astype(np.float32))
    return levels


class TextureTable:
    """Rows of the texture table, and image textures decoded to linear float32 RGB and
    concatenated row by row into one texel atlas (each row keeps its offset), each followed by
    its mip-map levels (textures.py)."""

    MAX_TEXELS = 1 << 26  # 64 Mi texels (768 MiB): a guard against decompression bombs

    def __init__(self, base_dir: Path, source: str, images: dict[str, np.ndarray] | None = None):
        self.base_dir = Path(base_dir)
        self.source = source
        self.images = images or {}  # decoded images by ImageTexture.file (a glTF file's textures)
        self.rows: list[np.ndarray] = []
        self.parts: list[np.ndarray] = []
        self.size = 0
        self.loaded: dict[tuple[Path, str], tuple] = {}

    def add(self, texture, where: str) -> int:
        """The row of a model texture (checker or image), normal, bump or alpha map."""
        row = np.zeros(X.TEX_WIDTH, dtype=np.float64)
        if isinstance(texture, (ImageTexture, NormalMap, BumpMap, AlphaMap)):
            # colours sRGB-decoded; maps of normals and heights as stored, unless a bump map says
            # its heights are sRGB-encoded; masks their alpha channel (or grey) as stored, unless sRGB-encoded
            if isinstance(texture, AlphaMap):
                reading = "coverage" if texture.encoding == "linear" else "coverage-srgb"
            elif isinstance(texture, NormalMap) or (isinstance(texture, BumpMap) and texture.encoding == "linear"):
                reading = "raw"
            else:
                reading = "srgb"
            key = {NormalMap: "normal_map", BumpMap: "bump_map", AlphaMap: "alpha_map"}.get(type(texture), "texture")
            offset, tex_w, tex_h, levels, mean = self._image(texture.file, f"{where}.{key}.file", reading)
            row[X.TEX_KIND] = X.IMAGE
            row[X.TEX_COLOR_A : X.TEX_COLOR_A + 3] = mean
            row[X.TEX_OFFSET] = offset
            row[X.TEX_WIDTH_PX] = tex_w
            row[X.TEX_HEIGHT_PX] = tex_h
            row[X.TEX_LEVELS] = levels
            row[X.TEX_SCALE_U] = texture.scale[0]
            row[X.TEX_SCALE_V] = texture.scale[1]
        else:
            row[X.TEX_KIND] = X.CHECKER
            row[X.TEX_COLOR_A : X.TEX_COLOR_A + 3] = texture.colors[0]
            row[X.TEX_COLOR_B : X.TEX_COLOR_B + 3] = texture.colors[1]
            row[X.TEX_CELL] = texture.scale
        self.rows.append(row)
        return len(self.rows) - 1

    def _image(self, file: str, where: str, reading: str = "srgb") -> tuple[int, int, int, int, np.ndarray]:
        """(offset, width, height, mip levels, mean colour) of the image, loading it once for each
        way it is read: "srgb" (colours, decoded), "raw" (normal and height maps, as stored) or
        "coverage" (masks: the alpha channel, or the grey, as stored, in all three channels;
        "coverage-srgb" the same decoded from sRGB)."""
        path = Path(file)
        if not path.is_absolute():
            path = self.base_dir / path
        key = (path.resolve(), reading)
        if key not in self.loaded:
            texels = self.images[file] if file in self.images else self._load(path, where, reading)
            h, w = texels.shape[:2]
            levels = mip_levels(texels)
            self.loaded[key] = (self.size, w, h, len(levels), texels.reshape(-1, 3).mean(axis=0, dtype=np.float64))
            for level in levels:
                self.parts.append(level.reshape(-1, 3))
                self.size += level.shape[0] * level.shape[1]
        return self.loaded[key]

    def _load(self, path: Path, where: str, reading: str = "srgb") -> np.ndarray:
        from PIL import Image as PILImage

        def fail(why: str):
            raise SceneError(f"{self.source}: {where}: {why}")

        if not path.exists():
            fail(f"texture file {path} does not exist")
        if path.is_dir():
            fail(f"texture file {path} is a folder")
        try:
            with PILImage.open(path) as im:
                if im.width * im.height > self.MAX_TEXELS:
                    fail(f"texture {path} is {im.width} x {im.height}, more than {self.MAX_TEXELS} texels")
                rgb = _coverage_of(im) if reading.startswith("coverage") else _rgb_of(im)
                if sixteen_bit_colour_png(path, im):
                    warn(
                        f"{self.source}: {where}: {path} is a PNG of 16-bit colour, which is read at 8 bits (Pillow "
                        "decodes no more); save a bump map or mask as 16-bit greyscale, which is read whole"
                    )
        except SceneError:
            raise
        except (OSError, ValueError, PILImage.DecompressionBombError) as exc:
            fail(f"cannot read texture {path} as an image (PNG or JPEG): {exc}")
        return (srgb_to_linear(rgb) if reading in ("srgb", "coverage-srgb") else rgb).astype(np.float32)

    def table(self) -> np.ndarray:
        if not self.rows:
            return np.zeros((1, X.TEX_WIDTH), dtype=np.float64)
        return np.stack(self.rows)

    def texels(self) -> np.ndarray:
        if not self.parts:
            return np.zeros((1, 3), dtype=np.float32)
        return np.ascontiguousarray(np.concatenate(self.parts), dtype=np.float32)


def material_row(mat: Material, textures: TextureTable | None = None, where: str = "material") -> np.ndarray:
    """The material's row of the materials table: the columns of its kind, packed by the kind's
    module (its trace-mode approximation in the phong columns), then those every kind has;
    its texture and maps are added to `textures`."""
    row = np.zeros(M.MAT_WIDTH, dtype=np.float64)
    M.pack_material(mat, row)
    row[M.MAT_COLOR : M.MAT_COLOR + 3] = mat.color
    row[M.MAT_EMISSION : M.MAT_EMISSION + 3] = mat.emission
    row[M.MAT_TEXTURE] = -1
    if mat.texture is not None:
        if textures is None:
            raise ValueError("a textured material needs a TextureTable")
        row[M.MAT_TEXTURE] = textures.add(mat.texture, where)
    if mat.normal_map is not None:
        if textures is None:
            raise ValueError("a normal-mapped material needs a TextureTable")
        row[M.MAT_NORMAL_MAP] = 1 + textures.add(mat.normal_map, where)
        row[M.MAT_NORMAL_STRENGTH] = mat.normal_map.strength
    if mat.bump_map is not None:
        if textures is None:
            raise ValueError("a bump-mapped material needs a TextureTable")
        row[M.MAT_BUMP_MAP] = 1 + textures.add(mat.bump_map, where)
        row[M.MAT_BUMP_HEIGHT] = mat.bump_map.height
    if mat.alpha_map is not None:
        if textures is None:
            raise ValueError("an alpha-mapped material needs a TextureTable")
        row[M.MAT_ALPHA_MAP] = 1 + textures.add(mat.alpha_map, where)
        row[M.MAT_ALPHA_CUTOFF] = mat.alpha_map.cutoff
    return row


def material_table(
    materials: dict, where: dict, base_dir: Path, source: str, images: dict[str, np.ndarray]
) -> tuple[np.ndarray, TextureTable]:
    """The material table, rows in the order of `materials` (model -> row), and its textures."""
    textures = TextureTable(base_dir, source, images)
    rows = np.stack([material_row(m, textures, where.get(m, "material")) for m in materials])
    return rows, textures
