"""PNG charts of a design (matplotlib, Agg backend): the circumference profile with B, B1,
C, D; target versus predicted pressure inside the class band; the unrolled pressure map."""

from __future__ import annotations

import io

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from app.geometry.anatomy import LANDMARK_NAMES as LANDMARKS  # noqa: E402
from app.geometry.garment.pressure import PA_PER_MMHG, surface_rings  # noqa: E402
from app.geometry.garment.standards import GRADIENT  # noqa: E402
from app.records.codec import CalfRecord  # noqa: E402

CHARTS = ("profile", "pressure", "map")


def _png(fig) -> bytes:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    return buffer.getvalue()


def profile_chart(record: CalfRecord, result: dict) -> bytes:
    z = [record.landmarks[n]["height_mm"] for n in LANDMARKS]
    heights = np.linspace(z[0], z[-1], 150)
    rings = surface_rings(record.surface, heights, 360)
    fig, ax = plt.subplots(figsize=(5.5, 6))
    ax.plot(rings.perimeter / 10, heights, label="skin circumference (surface)", color="tab:blue")
    ax.plot(rings.hull_perimeter / 10, heights, "--", label="stretched fabric (convex hull)", color="tab:orange")
    spec = result["knitting_spec"]
    ax.plot([r["relaxed_circumference_mm"] / 10 for r in spec], [r["height_mm"] for r in spec], ":",
            label="relaxed knitted circumference L0", color="tab:green")
    for name in LANDMARKS:
        lm = result["landmarks"][name]
        ax.axhline(lm["height_mm"], color="0.8", lw=0.8)
        ax.annotate(f"{name} {lm['skin_circumference_mm'] / 10:.1f} cm", (lm["skin_circumference_mm"] / 10, lm["height_mm"]),
                    textcoords="offset points", xytext=(6, 3), fontsize=8)
        ax.plot(lm["skin_circumference_mm"] / 10, lm["height_mm"], "o", color="tab:red", ms=4)
    ax.set_xlabel("circumference (cm)")
    ax.set_ylabel("height above B (mm)")
    ax.set_title("Circumference profile C(h)")
    ax.legend(fontsize=8, loc="lower right")
    return _png(fig)


def pressure_chart(result: dict) -> bytes:
    spec = result["knitting_spec"]
    h = np.array([r["height_mm"] for r in spec])
    fig, ax = plt.subplots(figsize=(5.5, 6))
    if result.get("class"):
        lo, hi = result["class"]["range_mmHg"]
        hi = hi if hi is not None else lo * 1.3
        zs = [result["landmarks"][n]["height_mm"] for n in LANDMARKS]
        band_lo = [lo] + [lo * GRADIENT[n]["range"][0] for n in LANDMARKS[1:]]
        band_hi = [hi] + [hi * GRADIENT[n]["range"][1] for n in LANDMARKS[1:]]
        ax.fill_betweenx(zs, band_lo, band_hi, color="tab:green", alpha=0.15,
                         label=f"{result['class']['standard']} class {result['class']['class']} x gradient table")
    ax.plot([r["target_mmHg"] for r in spec], h, "k--", label="target mean")
    ax.plot([r["predicted_mean_mmHg"] for r in spec], h, color="tab:blue", label="predicted mean (knitted L0)")
    for name in LANDMARKS:
        lm = result["landmarks"][name]
        sides = lm["sides_mmHg"]
        ax.plot(list(sides.values()), [lm["height_mm"]] * len(sides), "x", color="tab:red", ms=5)
        ax.annotate(name, (lm["mean_pressure_mmHg"], lm["height_mm"]), textcoords="offset points", xytext=(5, 4), fontsize=8)
    ax.plot([], [], "x", color="tab:red", label="medial / lateral / anterior / posterior")
    ax.set_xlabel("pressure (mmHg)")
    ax.set_ylabel("height above B (mm)")
    ax.set_title("Graduated compression down the leg")
    ax.legend(fontsize=8)
    return _png(fig)


def map_chart(result: dict, rings, local_pa: np.ndarray, top_mmhg: float) -> bytes:
    order = np.argsort(rings.angle[0])
    fig, ax = plt.subplots(figsize=(8, 5))
    image = ax.pcolormesh(np.degrees(rings.angle[0][order]), rings.heights_mm, (local_pa / PA_PER_MMHG)[:, order],
                          cmap="inferno", vmin=0, vmax=top_mmhg, shading="nearest")
    fig.colorbar(image, ax=ax, label="local pressure (mmHg)")
    for spot in result["hot_spots"]:
        ax.plot(spot["angle_deg"], spot["height_mm"], "o", mfc="none", mec="cyan", ms=9)
    for angle, label in ((90, "anterior"), (270, "posterior")):
        ax.axvline(angle, color="white", lw=0.5, ls=":")
        ax.text(angle, rings.heights_mm[-1], label, color="k", ha="center", va="bottom", fontsize=8)
    ax.set_xlabel("angle around the leg (deg; 0 = +x, the subject's right; 90 = anterior)")
    ax.set_ylabel("height above B (mm)")
    ax.set_title(f"Unrolled pressure map (hot-spot limit {result['hot_spot_limit_mmHg']:g} mmHg, circles)")
    return _png(fig)
