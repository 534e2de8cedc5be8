"""Scene meshes -> world triangles -> one cached OccupancyGrid, rebuilt only when those meshes change.

A change is noticed two ways: a `depsgraph_update_post` handler marks the cache dirty when an object of the
collection (or its mesh) is updated, and a cheap signature (object names, world matrices, vertex and
triangle counts of the evaluated meshes) is compared on every use, which also catches animated props
moving under `frame_set` (where depsgraph_update_post does not fire).
"""
from __future__ import annotations

from typing import Any

import bpy
import numpy as np

from ._runtime import UserError, runtime
from .rig import EGO_MARK

MAX_TRIANGLES = 5_000_000   # beyond this a voxelisation takes tens of seconds: ask for a smaller collection
VOXEL_SIZE = 0.05


def _is_character_mesh(ob: bpy.types.Object) -> bool:
    """Bodies skinned to or parented under an armature (the partner's, the ego's) are not scenery."""
    if EGO_MARK in ob:
        return True
    p = ob.parent
    while p is not None:
        if p.type == 'ARMATURE':
            return True
        p = p.parent
    return any(m.type == 'ARMATURE' and m.object is not None for m in ob.modifiers)


def _mesh_objects(collection: bpy.types.Collection) -> list[bpy.types.Object]:
    # Non-mesh geometry (curves, text) is left out: the model needs floors, walls and furniture.
    return sorted((ob for ob in collection.all_objects if ob.type == 'MESH' and not _is_character_mesh(ob)),
                  key=lambda ob: ob.name)


def signature(collection: bpy.types.Collection, depsgraph: bpy.types.Depsgraph) -> tuple:
    sig: list[Any] = []
    for ob in _mesh_objects(collection):
        oe = ob.evaluated_get(depsgraph)
        me = oe.data
        sig.append((ob.name, tuple(round(v, 6) for row in oe.matrix_world for v in row),
                    len(me.vertices), len(me.loop_triangles)))
    return tuple(sig)


def world_triangles(collection: bpy.types.Collection, depsgraph: bpy.types.Depsgraph
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (N, 3) float64 world, faces (M, 3) int64) of the evaluated meshes (modifiers applied)."""
    verts, faces, offset = [], [], 0
    total = 0
    for ob in _mesh_objects(collection):
        oe = ob.evaluated_get(depsgraph)
        me = oe.data
        nv, nt = len(me.vertices), len(me.loop_triangles)
        if nv == 0 or nt == 0:
            continue
        total += nt
        if total > MAX_TRIANGLES:
            raise UserError(f"Collection '{collection.name}' has more than {MAX_TRIANGLES:,} triangles; "
                            "pick fewer or simpler meshes (decimate them) for the scene")
        co = np.empty(nv * 3, dtype=np.float32)
        me.vertices.foreach_get("co", co)
        tri = np.empty(nt * 3, dtype=np.int32)
        me.loop_triangles.foreach_get("vertices", tri)
        mw = np.array(oe.matrix_world, dtype=np.float64)
        v = co.reshape(nv, 3).astype(np.float64) @ mw[:3, :3].T + mw[:3, 3]
        if not np.isfinite(v).all() or np.abs(v).max() > 1.0e5:   # Blender stores inf as float32 max
            raise UserError(f"Mesh '{ob.name}' has NaN or infinite coordinates (check its transform); "
                            "fix it or leave it out of the scene collection")
        verts.append(v)
        faces.append(tri.reshape(nt, 3).astype(np.int64) + offset)
        offset += nv
    if not faces:
        raise UserError(f"Collection '{collection.name}' has no mesh triangles; add meshes to it or clear "
                        "the Scene field")
    return np.concatenate(verts), np.concatenate(faces)


class SceneCache:
    """One OccupancyGrid for one collection, rebuilt only when its meshes change."""

    def __init__(self) -> None:
        self._grid: Any = None
        self._key: tuple | None = None
        self._dirty = True
        self._names: set[str] = set()
        self._meshes: set[str] = set()
        self.builds = 0            # how many times the grid was (re)built: tests and the status line
        self.build_seconds = 0.0

    def mark_dirty(self) -> None:
        self._dirty = True

    def grid(self, collection: bpy.types.Collection | None, depsgraph: bpy.types.Depsgraph) -> Any:
        """The grid for `collection` (None when there is none)."""
        if collection is None:
            self._grid, self._key = None, None
            return None
        try:
            key = (collection.name, signature(collection, depsgraph))
        except ReferenceError:
            raise UserError("The scene collection was deleted; pick another one") from None
        if self._dirty or key != self._key or self._grid is None:
            import time
            t0 = time.perf_counter()
            v, f = world_triangles(collection, depsgraph)
            og = runtime().OccupancyGrid
            self._grid = og.from_triangles(v, f, voxel_size=VOXEL_SIZE)
            self.build_seconds = time.perf_counter() - t0
            self.builds += 1
            self._key = key
            self._dirty = False
            obs = _mesh_objects(collection)
            self._names = {ob.name for ob in obs}
            self._meshes = {ob.data.name for ob in obs}
        return self._grid

    def on_depsgraph_update(self, collection: bpy.types.Collection | None,
                            depsgraph: bpy.types.Depsgraph) -> None:
        """Mark dirty when an update touches one of the collection's meshes."""
        if collection is None or self._dirty:
            return
        try:
            coll_name = collection.name
        except ReferenceError:
            self._dirty = True
            return
        names, meshes = self._names, self._meshes
        for upd in depsgraph.updates:
            idb = upd.id
            if isinstance(idb, bpy.types.Object) and idb.name in names:
                self._dirty = True
                return
            if isinstance(idb, bpy.types.Mesh) and idb.name in meshes and upd.is_updated_geometry:
                self._dirty = True
                return
            if isinstance(idb, bpy.types.Collection) and idb.name == coll_name:
                self._dirty = True
                return
