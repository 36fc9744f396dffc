"""Reading a glTF the export wrote, for the glTF tests: the file and an accessor's values as numpy arrays."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pygltflib


def load(path: Path) -> pygltflib.GLTF2:
    """The glTF (``.glb`` or ``.gltf``) at ``path``."""
    gltf = pygltflib.GLTF2().load(str(path))
    assert gltf is not None
    return gltf


def accessor(gltf: pygltflib.GLTF2, index: int) -> np.ndarray:
    """An accessor's values, (count, components), in its component type (float32, uint16 or uint8)."""
    acc = gltf.accessors[index]
    view = gltf.bufferViews[acc.bufferView]
    dtype = {pygltflib.FLOAT: np.float32, pygltflib.UNSIGNED_SHORT: np.uint16,
             pygltflib.UNSIGNED_BYTE: np.uint8}[acc.componentType]
    width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}[acc.type]
    data = gltf.binary_blob()[view.byteOffset + (acc.byteOffset or 0):view.byteOffset + view.byteLength]
    return np.frombuffer(data, dtype=dtype, count=acc.count * width).reshape(acc.count, width)
