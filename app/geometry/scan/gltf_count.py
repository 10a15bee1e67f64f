"""How many points and triangles a glTF scene expands to, read from its JSON alone.

A glTF 2.0 file (Khronos glTF 2.0 specification, sections 3.5 "Scenes", 3.7
"Geometry", 3.6 "Accessors"; GLB: section 4 "Binary glTF Layout") stores each mesh
once and *instances* it from the scene's nodes: a node names a mesh and child nodes,
and the same node may be the child of many (the node graph is a DAG), and the
EXT_mesh_gpu_instancing extension repeats a node's mesh once per entry of its
TRANSLATION/ROTATION/SCALE accessors.  A scan reader that flattens the scene
(trimesh's ``Scene.dump``) allocates every instance: a 1.3 MB file that instances a
mesh 400 times becomes 5 GB.  :func:`gltf_scene_size` counts what the flattening would
produce - per node, its own mesh's counts times its instances, plus its children's,
counted so that a DAG of depth d and fan-out k costs O(nodes + edges), not k^d - so
that the reader can refuse a scene past its limits before anything is expanded.  A
scanner writes each mesh once; a scene that instances one mesh more than
:data:`MAX_MESH_INSTANCES` times is refused whatever its size (it is copies, not a scan).

Counts: points = POSITION accessor counts; triangles = index count / 3 for mode 4
(TRIANGLES, the default), count - 2 for strips (5) and fans (6), by POSITION count when
a primitive has no indices; point primitives (mode 0) count points only.
"""

from __future__ import annotations

import json
import struct
from dataclasses import dataclass

from app.geometry.errors import FailureReason, FitFailure

GLB_MAGIC = b"glTF"
JSON_CHUNK = 0x4E4F534A  # "JSON"
#: a scan stores each of its meshes once: a scene that shows one mesh more often than
#: this is a scene of copies, not a scan (refused before it is expanded)
MAX_MESH_INSTANCES = 4


@dataclass(frozen=True)
class SceneSize:
    """What the default scene expands to: ``points`` (vertices), ``triangles``, and
    ``max_instances``, the most times one mesh appears in it."""

    points: int
    triangles: int
    max_instances: int = 1


def _unreadable(detail: str) -> FitFailure:
    return FitFailure(FailureReason.UNREADABLE_FILE, detail)


def gltf_json(data: bytes, fmt: str) -> dict:
    """The JSON of a GLB (its first chunk) or of a glTF text file."""
    if fmt == "glb":
        if len(data) < 20 or data[:4] != GLB_MAGIC:
            raise _unreadable("the file could not be read as GLB: it does not start with the glTF binary header")
        chunk_length, chunk_type = struct.unpack_from("<II", data, 12)
        if chunk_type != JSON_CHUNK or 20 + chunk_length > len(data):
            raise _unreadable("the file could not be read as GLB: its first chunk is not the glTF JSON")
        text = data[20:20 + chunk_length]
    else:
        text = data
    try:
        document = json.loads(text)
    except (ValueError, UnicodeDecodeError, RecursionError) as exc:
        raise _unreadable(f"the file could not be read as {fmt.upper()}: its glTF JSON is not valid JSON") from exc
    if not isinstance(document, dict):
        raise _unreadable(f"the file could not be read as {fmt.upper()}: its glTF JSON is not an object")
    return document


def _count(accessors: list, index) -> int:
    if not isinstance(index, int) or not 0 <= index < len(accessors) or not isinstance(accessors[index], dict):
        raise _unreadable("the glTF names an accessor it does not have")
    count = accessors[index].get("count", 0)
    if not isinstance(count, int) or count < 0:
        raise _unreadable("a glTF accessor has no valid count")
    return count


def _mesh_size(mesh: dict, accessors: list) -> tuple[int, int]:
    points = triangles = 0
    for primitive in mesh.get("primitives") or []:
        if not isinstance(primitive, dict):
            continue
        attributes = primitive.get("attributes") or {}
        n = _count(accessors, attributes["POSITION"]) if "POSITION" in attributes else 0
        points += n
        mode = primitive.get("mode", 4)
        corners = _count(accessors, primitive["indices"]) if "indices" in primitive else n
        if mode == 4:
            triangles += corners // 3
        elif mode in (5, 6):
            triangles += max(corners - 2, 0)
    return points, triangles


def gltf_scene_size(document: dict) -> SceneSize:
    """Points and triangles of the default scene (or of every root node when the file
    names no scene), every instance counted; see the module docstring.

    The instances of each node are the number of paths to it from the scene's roots
    (times each parent's listing of it), counted in topological order of the node DAG
    (Kahn's algorithm: O(nodes + edges)); a node graph with a cycle is unreadable."""
    nodes = document.get("nodes") or []
    meshes = document.get("meshes") or []
    accessors = document.get("accessors") or []
    if not all(isinstance(x, list) for x in (nodes, meshes, accessors)):
        raise _unreadable("the glTF's nodes, meshes and accessors must be lists")

    def node_index(index) -> int:
        if not isinstance(index, int) or not 0 <= index < len(nodes) or not isinstance(nodes[index], dict):
            raise _unreadable("the glTF scene names a node it does not have")
        return index

    children = [[node_index(c) for c in (node.get("children") or [])] if isinstance(node, dict) else [] for node in nodes]
    scenes = document.get("scenes")
    if isinstance(scenes, list) and scenes:
        chosen = document.get("scene", 0)
        scene = scenes[chosen] if isinstance(chosen, int) and 0 <= chosen < len(scenes) else scenes[0]
        roots = [node_index(r) for r in ((scene.get("nodes") or []) if isinstance(scene, dict) else [])]
    else:
        listed = {c for kids in children for c in kids}
        roots = [i for i in range(len(nodes)) if i not in listed]
    # the nodes reachable from the roots, and how many edges lead into each
    reachable, stack = set(roots), list(roots)
    while stack:
        for child in children[stack.pop()]:
            if child not in reachable:
                reachable.add(child)
                stack.append(child)
    incoming = dict.fromkeys(reachable, 0)
    for index in reachable:
        for child in children[index]:
            incoming[child] += 1
    paths = dict.fromkeys(reachable, 0)
    for root in roots:
        paths[root] += 1
    ready = [i for i in reachable if incoming[i] == 0]
    done = 0
    while ready:
        index = ready.pop()
        done += 1
        for child in children[index]:
            paths[child] += paths[index]
            incoming[child] -= 1
            if incoming[child] == 0:
                ready.append(child)
    if done != len(reachable):
        raise _unreadable("the glTF node graph has a cycle")
    mesh_instances: dict[int, int] = {}
    for index in reachable:
        node = nodes[index]
        if "mesh" not in node:
            continue
        m = node["mesh"]
        if not isinstance(m, int) or not 0 <= m < len(meshes) or not isinstance(meshes[m], dict):
            raise _unreadable("a glTF node names a mesh the file does not have")
        copies = 1
        instancing = (node.get("extensions") or {}).get("EXT_mesh_gpu_instancing")
        if isinstance(instancing, dict):
            counts = [_count(accessors, a) for a in (instancing.get("attributes") or {}).values()]
            copies = max(counts) if counts else 1
        mesh_instances[m] = mesh_instances.get(m, 0) + paths[index] * copies
    points = triangles = 0
    for m, instances in mesh_instances.items():
        p, t = _mesh_size(meshes[m], accessors)
        points, triangles = points + p * instances, triangles + t * instances
    return SceneSize(points, triangles, max(mesh_instances.values(), default=0))
