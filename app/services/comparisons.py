"""Two records of one leg compared: the service behind GET /records/{a}/compare/{b}.

The numbers come from :mod:`app.geometry.measures.compare`; this layer fetches both records
(the tenant's only), refuses two different legs, and renders the result as JSON, a
GLB with vertex colours or CSV.
"""

from __future__ import annotations

import io

import numpy as np
import trimesh

from app.errors import Unprocessable
from app.geometry.measures.compare import alignment_shift, compare_surfaces, shared_heights, signed_differences
from app.records.meshes import apply_frame
from app.services.records import RecordService, _parse

#: the colour map of the difference map runs from -MAP_RANGE_MM (blue, the leg has
#: shrunk) through white to +MAP_RANGE_MM (red, swollen) unless a larger difference
#: needs more; 5 mm of radius is about 3 cm of girth, well past a refit
MAP_RANGE_MM = 5.0
COLORMAP = "coolwarm"


class ComparisonService:
    def __init__(self, session, tenant_id: str):
        self.records = RecordService(session, tenant_id)

    def pair(self, a_id: str, b_id: str):
        a, b = self.records.get(a_id), self.records.get(b_id)
        ra, rb = _parse(a.body), _parse(b.body)
        if ra.side and rb.side and ra.side != rb.side:
            raise Unprocessable(f"record {a_id} is a {ra.side} leg and record {b_id} a {rb.side} leg: "
                                "only two records of the same leg can be compared", code="different_legs")
        return a, ra, b, rb

    def compare(self, a_id: str, b_id: str, align: str) -> dict:
        a, ra, b, rb = self.pair(a_id, b_id)
        comparison = self._comparison(ra, rb, align)
        diff = comparison.girth_b_mm - comparison.girth_a_mm
        return {
            "record_a": a.id,
            "record_b": b.id,
            "align": align,
            "shift_mm": comparison.shift_mm,
            "girths": [{"height_mm": float(h), "girth_a_mm": float(ga), "girth_b_mm": float(gb), "difference_mm": float(d)}
                       for h, ga, gb, d in zip(comparison.heights_mm, comparison.girth_a_mm, comparison.girth_b_mm, diff)],
            "volume": {
                "low_mm": comparison.low_mm,
                "high_mm": comparison.high_mm,
                "a_ml": comparison.volume_a_mm3 / 1000.0,
                "b_ml": comparison.volume_b_mm3 / 1000.0,
                "change_ml": comparison.volume_change_mm3 / 1000.0,
                "change_percent": comparison.volume_change_percent,
            },
            "largest_girth_change_mm": float(diff[np.nanargmax(np.abs(diff))]) if np.isfinite(diff).any() else None,
        }

    @staticmethod
    def _comparison(ra, rb, align: str):
        try:
            return compare_surfaces(ra.surface, ra.landmarks, rb.surface, rb.landmarks, align)
        except KeyError as exc:
            raise Unprocessable(f"a record has no landmark {align}", code="invalid_alignment") from exc
        except ValueError as exc:
            raise Unprocessable(str(exc), code="no_overlap") from exc

    def difference_map(self, a_id: str, b_id: str, align: str, file_format: str) -> bytes:
        """The signed difference map on record a's surface: GLB (scan coordinates of a,
        vertex colours, legend in the scene's extras) or CSV (calf frame of a, mm)."""
        _, ra, _, rb = self.pair(a_id, b_id)
        try:  # the map needs only the alignment and the overlap, not the girths and volumes
            shift = alignment_shift(ra.landmarks, rb.landmarks, align)
            shared_heights(ra.surface, rb.surface, shift)
        except KeyError as exc:
            raise Unprocessable(f"a record has no landmark {align}", code="invalid_alignment") from exc
        except ValueError as exc:
            raise Unprocessable(str(exc), code="no_overlap") from exc
        vertices, faces, signed = signed_differences(ra.surface, rb.surface, shift)
        base = float(ra.landmarks[align]["height_mm"])
        if file_format == "csv":
            out = io.StringIO()
            out.write("x_mm,y_mm,z_mm,height_above_" + align + "_mm,signed_difference_mm\n")
            rows = np.column_stack([vertices, vertices[:, 2] - base, signed])
            np.savetxt(out, rows, delimiter=",", fmt=["%.3f", "%.3f", "%.3f", "%.3f", "%.4f"])
            return out.getvalue().replace("nan", "").encode()
        import matplotlib

        top = max(MAP_RANGE_MM, float(np.nanmax(np.abs(signed))) if np.isfinite(signed).any() else 0.0)
        cmap = matplotlib.colormaps[COLORMAP]
        shade = np.clip(0.5 + 0.5 * np.nan_to_num(signed) / top, 0.0, 1.0)
        colors = (cmap(shade) * 255).astype(np.uint8)
        colors[~np.isfinite(signed)] = (160, 160, 160, 255)  # b does not reach: grey
        mesh = trimesh.Trimesh(apply_frame(vertices, ra.frame), faces, process=False)
        mesh.visual.vertex_colors = colors
        scene = trimesh.Scene()
        scene.add_geometry(mesh, node_name="difference_map", geom_name="difference_map")
        scene.metadata["legend"] = {"quantity": "signed distance from record a to record b (+: b outside a)",
                                    "unit": "mm", "colormap": COLORMAP, "bottom_mm": -top, "top_mm": top,
                                    "no_data": "grey: record b does not reach this height"}
        return scene.export(file_type="glb")
