"""Exact CAD exports of a record's surface: STEP, IGES, Rhino .3dm and geomdl JSON.

No tessellation: each format receives the B-spline itself - degrees, the full knot
vectors, the control net and the weights - so a CAD program evaluates the very surface
the service evaluates (The NURBS Book, A3.5/A4.3, in any conforming reader).

Geometry: the surface is written in the record's own frame, in millimetres - B at the
origin, z up the leg, y anterior (the calf frame); the record's ``frame`` matrix places
it in the scan.  The periodic u direction is written in its unwrapped, non-periodic form
(the first 3 control columns repeated, every knot written out; see
:mod:`app.geometry.spline.nurbs`), which every NURBS reader evaluates identically; the valid
domain is [knots_u[3], knots_u[nu]] x [knots_v[3], knots_v[nv]].

- STEP (ISO 10303-21, schema AP214) and IGES 5.3 through OpenCASCADE (``cadquery-ocp``):
  a ``Geom_BSplineSurface`` made into a face; STEP's length unit and IGES's are mm.
- Rhino ``.3dm`` through ``rhino3dm`` (openNURBS): a NurbsSurface of order 4 x 4; the
  openNURBS knot vector omits the first and last knot of the full one; model unit mm.
- geomdl JSON: the layout of NURBS-Python's ``exchange.export_json`` (``shape.data[0]``
  with ``degree_u/v``, ``knotvector_u/v``, ``size_u/v``, control points u-major).

The OpenCASCADE and openNURBS libraries are imported on first use (they are large).
The OpenCASCADE bindings are those of ``cadquery-ocp`` 8 (NCollection arrays as
``OCP.collections.Array*``), pinned in ``pyproject.toml``.
"""

from __future__ import annotations

import json
import os
import tempfile

import numpy as np

from app.geometry.spline.nurbs import NurbsSurface

CAD_FORMATS = ("step", "iges", "3dm", "geomdl")
CAD_MEDIA_TYPES = {
    "step": "model/step",
    "iges": "model/iges",
    "3dm": "model/vnd.3dm",
    "geomdl": "application/vnd.geomdl+json",
}
CAD_EXTENSIONS = {"step": "step", "iges": "igs", "3dm": "3dm", "geomdl": "json"}
#: formats whose writers stamp the time of writing into the file (the same surface is
#: written to different bytes)
TIMESTAMPED_FORMATS = ("step", "iges", "3dm")


def _unique_knots(knots: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distinct knot values and their multiplicities (OpenCASCADE's knot form)."""
    values, counts = [], []
    for k in knots:
        if values and abs(k - values[-1]) <= 1e-12 * max(1.0, abs(k)):
            counts[-1] += 1
        else:
            values.append(float(k))
            counts.append(1)
    return np.array(values), np.array(counts)


def occ_surface(surface: NurbsSurface):
    """The surface as an OpenCASCADE ``Geom_BSplineSurface`` (non-periodic form)."""
    from OCP.collections import Array1_double, Array1_int, Array2_double, Array2_gp_Pnt
    from OCP.Geom import Geom_BSplineSurface
    from OCP.gp import gp_Pnt

    nu, nv = surface.shape
    poles = Array2_gp_Pnt(1, nu, 1, nv)
    weights = Array2_double(1, nu, 1, nv)
    for i in range(nu):  # a few hundred control points: the OCC arrays are set one by one
        for j in range(nv):
            x, y, z = (float(c) for c in surface.control_points[i, j])
            poles.SetValue(i + 1, j + 1, gp_Pnt(x, y, z))
            weights.SetValue(i + 1, j + 1, float(surface.weights[i, j]))

    def knot_arrays(knots):
        values, mults = _unique_knots(knots)
        k = Array1_double(1, len(values))
        m = Array1_int(1, len(values))
        for i, (value, mult) in enumerate(zip(values, mults)):
            k.SetValue(i + 1, float(value))
            m.SetValue(i + 1, int(mult))
        return k, m

    ku, mu = knot_arrays(surface.knots_u)
    kv, mv = knot_arrays(surface.knots_v)
    return Geom_BSplineSurface(poles, weights, ku, kv, mu, mv, surface.degree_u, surface.degree_v, False, False)


def _quiet_occ() -> None:
    """OpenCASCADE's default messenger prints its translators' progress to stdout (a
    server's log); a writer's failure is its return status, which is checked."""
    from OCP.Message import Message

    Message.DefaultMessenger_s().ChangePrinters().Clear()


def _face(surface: NurbsSurface):
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace

    u0, u1 = surface.domain_u
    v0, v1 = surface.domain_v
    return BRepBuilderAPI_MakeFace(occ_surface(surface), u0, u1, v0, v1, 1e-7).Face()


def _written(write) -> bytes:
    """Bytes of a file a library writes to a path (it cannot write to memory)."""
    handle, path = tempfile.mkstemp(suffix=".cad")
    os.close(handle)
    try:
        write(path)
        with open(path, "rb") as stream:
            return stream.read()
    finally:
        os.unlink(path)


def to_step(surface: NurbsSurface) -> bytes:
    """STEP AP214 (ISO 10303-21) holding the surface as a face, mm."""
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.Interface import Interface_Static
    from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer

    _quiet_occ()
    Interface_Static.SetCVal_s("write.step.schema", "AP214IS")
    Interface_Static.SetCVal_s("write.step.unit", "MM")
    Interface_Static.SetCVal_s("write.step.product.name", "calf")
    writer = STEPControl_Writer()
    writer.Transfer(_face(surface), STEPControl_AsIs)

    def write(path):
        if writer.Write(path) != IFSelect_RetDone:
            raise RuntimeError("OpenCASCADE could not write the STEP file")

    return _written(write)


def to_iges(surface: NurbsSurface) -> bytes:
    """IGES 5.3 holding the surface as a face (B-spline surface entity 128), mm."""
    from OCP.IGESControl import IGESControl_Writer

    _quiet_occ()
    writer = IGESControl_Writer("MM", 0)
    writer.AddShape(_face(surface))
    writer.ComputeModel()

    def write(path):
        if not writer.Write(path):
            raise RuntimeError("OpenCASCADE could not write the IGES file")

    return _written(write)


def to_3dm(surface: NurbsSurface) -> bytes:
    """Rhino .3dm (openNURBS) holding the NurbsSurface, model unit mm."""
    import rhino3dm

    nu, nv = surface.shape
    rational = not np.allclose(surface.weights, 1.0)
    nurbs = rhino3dm.NurbsSurface.Create(3, rational, surface.degree_u + 1, surface.degree_v + 1, nu, nv)
    for i, knot in enumerate(surface.knots_u[1:-1]):  # openNURBS omits the end knots
        nurbs.KnotsU[i] = float(knot)
    for i, knot in enumerate(surface.knots_v[1:-1]):
        nurbs.KnotsV[i] = float(knot)
    for i in range(nu):
        for j in range(nv):
            x, y, z = (float(c) for c in surface.control_points[i, j])
            w = float(surface.weights[i, j])
            # homogeneous (w x, w y, w z, w), as openNURBS stores rational points
            nurbs.Points[i, j] = rhino3dm.Point4d(x * w, y * w, z * w, w)
    model = rhino3dm.File3dm()
    model.Settings.ModelUnitSystem = rhino3dm.UnitSystem.Millimeters
    model.Objects.AddSurface(nurbs)

    def write(path):
        if not model.Write(path, 7):
            raise RuntimeError("openNURBS could not write the .3dm file")

    return _written(write)


def to_geomdl(surface: NurbsSurface, name: str = "calf") -> bytes:
    """JSON in NURBS-Python (geomdl) ``exchange.export_json`` layout, mm."""
    nu, nv = surface.shape
    data = {
        "type": "spline",
        "name": name,
        "degree_u": surface.degree_u,
        "degree_v": surface.degree_v,
        "knotvector_u": [float(k) for k in surface.knots_u],
        "knotvector_v": [float(k) for k in surface.knots_v],
        "size_u": nu,
        "size_v": nv,
        "control_points": {
            "points": surface.control_points.reshape(-1, 3).tolist(),  # u-major: v varies fastest
            "weights": surface.weights.reshape(-1).tolist(),
        },
    }
    shape = {"shape": {"type": "surface", "count": 1, "data": [data]}}
    return json.dumps(shape).encode()


def export_surface(surface: NurbsSurface, file_format: str) -> bytes:
    """The surface in one of :data:`CAD_FORMATS`."""
    writers = {"step": to_step, "iges": to_iges, "3dm": to_3dm, "geomdl": to_geomdl}
    if file_format not in writers:
        raise ValueError(f"unknown CAD format {file_format!r}")
    return writers[file_format](surface)
