"""A glTF 2.0 file's JSON and binary data, read and checked: `.gltf` (JSON; buffers and images
in files beside it or in `data:` URIs) and `.glb` (one binary container of a JSON chunk and a
BIN chunk). Accessors come back as numpy arrays (normalized integers as floats, sparse
accessors applied). Every problem is a GltfError naming the file and the part of it that is
wrong (`accessors[3]`, `buffers[0].uri`), so the command line can print it and exit 2.

Read by hand rather than through trimesh: trimesh drops lights, all cameras but one,
instancing and exact colour factors, and its errors on broken files do not say what is broken.
"""

from __future__ import annotations

import base64
import io
import json
import struct
from pathlib import Path
from urllib.parse import unquote

import numpy as np

from .mesh import MeshError

COMPONENTS = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
GLB_MAGIC = b"glTF"
CHUNK_JSON = 0x4E4F534A
CHUNK_BIN = 0x004E4942
MAX_TEXELS = 1 << 26  # as compile.TextureTable: a guard against decompression bombs


class GltfError(MeshError):
    """A glTF file that is missing, malformed, inconsistent or uses what raylume cannot honour."""


class GltfFile:
    """The document (`doc`, the parsed JSON) and lazily read buffers of one glTF file."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        try:
            data = self.path.read_bytes()
        except FileNotFoundError:
            raise GltfError(f"glTF file {self.path} does not exist.") from None
        except IsADirectoryError:
            raise GltfError(f"glTF file {self.path} is a folder, not a file.") from None
        except OSError as exc:
            raise GltfError(f"glTF file {self.path} cannot be read: {exc.strerror or exc}.") from None
        if not data:
            self.fail("the file is empty")
        self.bin: bytes | None = None
        if data[:4] == GLB_MAGIC:
            text = self._glb(data)
        elif self.path.suffix.lower() == ".glb":
            self.fail("it does not start with the GLB magic bytes 'glTF' (not a binary glTF file)")
        else:
            text = data
        try:
            doc = json.loads(text)
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            self.fail(f"its JSON is invalid ({getattr(exc, 'msg', exc)})")
        if not isinstance(doc, dict):
            self.fail("its JSON is not an object")
        self.doc: dict = doc
        version = str(doc.get("asset", {}).get("version", "")) if isinstance(doc.get("asset"), dict) else ""
        if not version.startswith("2."):
            self.fail(f"asset.version is {version or 'missing'!r}; only glTF 2.0 is supported")
        self._buffers: dict[int, bytes] = {}

    def fail(self, what: str):
        raise GltfError(f"glTF file {self.path}: {what}.")

    def _glb(self, data: bytes) -> bytes:
        """The JSON chunk of a GLB container (its BIN chunk kept in self.bin)."""
        if len(data) < 20:
            self.fail(f"it is truncated: {len(data)} bytes, shorter than a GLB header and chunk header")
        _, version, length = struct.unpack_from("<4sII", data, 0)
        if version != 2:
            self.fail(f"its GLB container is version {version}; only version 2 is supported")
        if length > len(data):
            self.fail(f"it is truncated: its header says {length} bytes, the file has {len(data)}")
        at, text = 12, None
        while at + 8 <= length:
            size, kind = struct.unpack_from("<II", data, at)
            if at + 8 + size > length:
                self.fail(f"it is truncated: a chunk of {size} bytes at byte {at} runs past the end ({length} bytes)")
            chunk = data[at + 8 : at + 8 + size]
            if kind == CHUNK_JSON and text is None:
                text = chunk
            elif kind == CHUNK_BIN and self.bin is None:
                self.bin = chunk
            at += 8 + size
        if text is None:
            self.fail("its GLB container has no JSON chunk")
        return text

    # ------------------------------------------------------------------ the document

    def items(self, key: str) -> list:
        value = self.doc.get(key, [])
        if not isinstance(value, list):
            self.fail(f"{key} is not a list")
        return value

    def index(self, value, where: str) -> int:
        """`value` checked to be a list index: JSON has no integer type, so "0", 0.0, true and -1
        all parse, and each would otherwise read as some other element or a missing one."""
        if value is None:
            self.fail(f"{where} is missing; it must be an index (a whole number >= 0)")
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            text = json.dumps(value)
            self.fail(f"{where} must be an index (a whole number >= 0), got {text[:60]}{'...' * (len(text) > 60)}")
        return value

    def item(self, key: str, index, where: str) -> dict:
        """`doc[key][index]`, failing with `where` (the referring key path) when it is missing."""
        items = self.items(key)
        if not self.index(index, where) < len(items):
            self.fail(f"{where} refers to {key}[{index}], but the file has {len(items)} {key}")
        value = items[index]
        if not isinstance(value, dict):
            self.fail(f"{key}[{index}] is not an object")
        return value

    def number(self, value, where: str, default=None) -> float:
        if value is None and default is not None:
            return float(default)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
            self.fail(f"{where} is {value!r}, not a finite number")
        return float(value)

    def numbers(self, value, n: int, where: str, default=None) -> np.ndarray:
        if value is None and default is not None:
            return np.asarray(default, dtype=np.float64)
        if not isinstance(value, list) or len(value) != n:
            self.fail(f"{where} must be a list of {n} numbers, got {value!r}")
        return np.array([self.number(v, where) for v in value], dtype=np.float64)

    # ------------------------------------------------------------------ binary data

    def buffer(self, index, where: str) -> bytes:
        if self.index(index, where) in self._buffers:
            return self._buffers[index]
        buf = self.item("buffers", index, where)
        uri = buf.get("uri")
        if uri is None:
            if self.bin is None:
                self.fail(f"buffers[{index}] has no uri and the file has no GLB BIN chunk")
            data = self.bin
        else:
            data = self._uri(uri, f"buffers[{index}].uri", "buffer")
        length = buf.get("byteLength")
        if isinstance(length, bool) or not isinstance(length, int) or length < 0:
            self.fail(f"buffers[{index}].byteLength is {length!r}, not a byte count")
        if len(data) < length:
            self.fail(f"buffers[{index}] is truncated: byteLength says {length} bytes, the data has {len(data)}")
        self._buffers[index] = data
        return data

    def _uri(self, uri, where: str, what: str) -> bytes:
        if not isinstance(uri, str):
            self.fail(f"{where} is not a string")
        if uri.startswith("data:"):
            head, _, payload = uri.partition(",")
            if not head.endswith(";base64"):
                self.fail(f"{where}: only base64 data URIs are supported")
            try:
                return base64.b64decode(payload, validate=True)
            except ValueError:
                self.fail(f"{where}: its base64 data is invalid")
        path = self.path.parent / unquote(uri)
        try:
            return path.read_bytes()
        except FileNotFoundError:
            self.fail(f"{where}: the {what} file {path} does not exist")
        except OSError as exc:
            self.fail(f"{where}: the {what} file {path} cannot be read ({exc.strerror or exc})")

    def view(self, index, where: str) -> tuple[bytes, int, int, int | None]:
        """(buffer, first byte, byte length, byte stride or None) of bufferViews[index]."""
        view = self.item("bufferViews", index, where)
        here = f"bufferViews[{index}]"
        buffer = view.get("buffer")
        data = self.buffer(buffer, f"{here}.buffer")
        start = int(self.number(view.get("byteOffset"), f"{here}.byteOffset", 0))
        length = int(self.number(view.get("byteLength"), f"{here}.byteLength"))
        if start < 0 or length < 0 or start + length > len(data):
            self.fail(f"{here} spans bytes {start}..{start + length} of buffers[{buffer}], which has {len(data)}")
        stride = view.get("byteStride")
        return data, start, length, None if stride is None else int(self.number(stride, f"{here}.byteStride"))

    def accessor(self, index, where: str) -> np.ndarray:
        """accessors[index] as an array (count, width): float64 for floats and normalized
        integers, int64 for the others. `where` is the key path that refers to it."""
        acc = self.item("accessors", index, where)
        here = f"accessors[{index}] ({where})"
        ctype = acc.get("componentType")
        if not isinstance(ctype, int) or ctype not in COMPONENTS:
            self.fail(f"{here}: componentType {ctype!r} is not one of glTF's ({', '.join(map(str, COMPONENTS))})")
        if not isinstance(acc.get("type"), str) or acc["type"] not in WIDTHS:
            self.fail(f"{here}: type {acc.get('type')!r} is not one of {', '.join(WIDTHS)}")
        dtype = np.dtype(COMPONENTS[ctype]).newbyteorder("<")
        width = WIDTHS[acc["type"]]
        count = acc.get("count")
        if isinstance(count, bool) or not isinstance(count, int) or count < 0:
            self.fail(f"{here}: count is {count!r}, not a number of elements")
        values = np.zeros((count, width), dtype=dtype)
        if acc.get("bufferView") is not None:
            values = self._read(acc, dtype, width, count, here)
        if acc.get("sparse") is not None:
            values = self._sparse(acc["sparse"], values, dtype, width, here)
        if acc.get("normalized") and dtype.kind in "iu":
            top = float(np.iinfo(dtype).max)
            return np.maximum(values.astype(np.float64) / top, -1.0)
        return values.astype(np.float64 if dtype.kind == "f" else np.int64)

    def _read(self, acc: dict, dtype, width: int, count: int, here: str) -> np.ndarray:
        data, start, length, stride = self.view(acc["bufferView"], f"{here}.bufferView")
        item = dtype.itemsize * width
        stride = stride or item
        offset = int(self.number(acc.get("byteOffset"), f"{here}.byteOffset", 0))
        need = offset + stride * (count - 1) + item if count else 0
        if offset < 0 or stride < item or need > length:
            self.fail(
                f"{here} needs {need} bytes (offset {offset}, stride {stride}, {count} elements of {item} bytes) "
                f"of bufferViews[{acc['bufferView']}], which has {length}"
            )
        if count == 0:
            return np.zeros((0, width), dtype=dtype)
        return np.ndarray(
            (count, width), dtype=dtype, buffer=data, offset=start + offset, strides=(stride, dtype.itemsize)
        ).copy()

    def _sparse(self, sparse: dict, values: np.ndarray, dtype, width: int, here: str) -> np.ndarray:
        n = int(self.number(sparse.get("count"), f"{here}.sparse.count"))
        ind, val = sparse.get("indices") or {}, sparse.get("values") or {}
        itype = ind.get("componentType")
        if not isinstance(itype, int) or itype not in (5121, 5123, 5125):
            self.fail(f"{here}.sparse.indices.componentType is {itype!r}, not an unsigned integer type")
        fake = {"bufferView": ind.get("bufferView"), "byteOffset": ind.get("byteOffset", 0)}
        indices = self._read(fake, np.dtype(COMPONENTS[itype]).newbyteorder("<"), 1, n, f"{here}.sparse.indices")
        fake = {"bufferView": val.get("bufferView"), "byteOffset": val.get("byteOffset", 0)}
        replace = self._read(fake, dtype, width, n, f"{here}.sparse.values")
        indices = indices.ravel().astype(np.int64)
        if n and indices.max() >= len(values):
            self.fail(f"{here}.sparse.indices refers to element {indices.max()} of {len(values)}")
        values = values.copy()
        values[indices] = replace
        return values

    def image(self, index, where: str, alpha: bool = False) -> np.ndarray:
        """images[index] decoded to uint8 RGB (H, W, 3), or RGBA (H, W, 4) with `alpha` (opaque
        where the image has no alpha channel, as glTF reads it), through Pillow."""
        from PIL import Image as PILImage

        img = self.item("images", index, where)
        here = f"images[{index}]"
        if img.get("uri") is not None:
            data = self._uri(img["uri"], f"{here}.uri", "texture")
            name = img["uri"] if not img["uri"].startswith("data:") else f"{here} (data URI)"
        elif img.get("bufferView") is not None:
            buf, start, length, _ = self.view(img["bufferView"], f"{here}.bufferView")
            data, name = buf[start : start + length], f"{here} (in bufferViews[{img['bufferView']}])"
        else:
            self.fail(f"{here} has neither a uri nor a bufferView")
        try:
            with PILImage.open(io.BytesIO(data)) as im:
                if im.width * im.height > MAX_TEXELS:
                    self.fail(f"texture {name} is {im.width} x {im.height}, more than {MAX_TEXELS} texels")
                return np.asarray(im.convert("RGBA" if alpha else "RGB"), dtype=np.uint8)
        except GltfError:
            raise
        except (OSError, ValueError, PILImage.DecompressionBombError) as exc:
            why = str(exc).split(" <_io.BytesIO")[0]  # (Pillow names the in-memory file by its repr)
            self.fail(f"texture {name} cannot be decoded as an image (PNG or JPEG): {why}")
