"""Export a performance (a :class:`~services.graphics.sequence.PoseSequence`) to BVH and glTF 2.0."""

from services.graphics.export.bvh import BvhInfo, write_bvh
from services.graphics.export.gltf import GltfInfo, write_gltf

__all__ = ["BvhInfo", "GltfInfo", "write_bvh", "write_gltf"]
