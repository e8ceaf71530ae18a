"""Read the Foxglove (protobuf) messages of a recording back into what the replay rebuilds snapshots from.

Messages are decoded with the schema the file carries (a FileDescriptorSet per schema record), so the replay
needs only `protobuf`, not the SDK that wrote them. Boxes come back from `/scene/boxes` (cube pose and size,
the entity metadata's id, yaw and dark), clouds from `foxglove.PointCloud`, depth from `foxglove.RawImage`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from mcap.records import Schema


class ProtobufDecoder:
    """bytes → protobuf message for the schemas of one file (message classes built once per schema id)."""

    def __init__(self) -> None:
        self._classes: dict[int, Any] = {}

    def decode(self, schema: Schema, data: bytes) -> Any:
        cls = self._classes.get(schema.id)
        if cls is None:
            cls = self._classes[schema.id] = _message_class(schema)
        return cls.FromString(data)


def _message_class(schema: Schema) -> Any:
    files = {f.name: f for f in descriptor_pb2.FileDescriptorSet.FromString(schema.data).file}
    pool = descriptor_pool.DescriptorPool()
    added: set[str] = set()

    def add(name: str) -> None:
        if name in added:
            return
        for dependency in files[name].dependency:
            add(dependency)
        pool.Add(files[name])
        added.add(name)

    for name in files:
        add(name)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(schema.name))


def _meta(entity: Any) -> dict[str, str]:
    return {kv.key: kv.value for kv in entity.metadata}


def boxes_message(update: Any) -> dict:
    """`/scene/boxes` (SceneUpdate) → the recording's box list: id, centre, full size, yaw, dark."""
    out = []
    for entity in update.entities:
        meta, cube = _meta(entity), entity.cubes[0]
        p, s = cube.pose.position, cube.size
        out.append({"id": meta["id"], "position": [p.x, p.y, p.z], "size": [s.x, s.y, s.z],
                    "yaw": float(meta["yaw"]), "dark": meta.get("dark") == "true"})
    return {"boxes": out}


def points_message(cloud: Any) -> dict:
    """`foxglove.PointCloud` of float32 x, y, z (world) → {"points": N×3}."""
    offsets = {f.name: f.offset for f in cloud.fields}
    if cloud.point_stride != 12 or [offsets.get(a) for a in "xyz"] != [0, 4, 8]:
        raise ValueError(f"point cloud of stride {cloud.point_stride} with fields {offsets}: expected float32 x y z")
    return {"points": np.frombuffer(cloud.data, dtype="<f4").reshape(-1, 3).astype(float)}


def depth_array(image: Any) -> np.ndarray:
    """`foxglove.RawImage` 32FC1 → H×W float32 metres."""
    if image.encoding != "32FC1":
        raise ValueError(f"depth image encoding {image.encoding!r}: expected 32FC1")
    return np.frombuffer(image.data, dtype="<f4").reshape(image.height, image.width).astype(np.float32)
