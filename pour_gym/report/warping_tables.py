"""The thesis's Tables 4.1-4.3 and the per-part IoU, beside the warp's numbers (chapter 4)."""

from __future__ import annotations

import numpy as np

from pour_gym.report.tables import markdown_table


def warping_tables(reports: dict[str, dict]) -> str:
    """Tables 4.1-4.3 and per-part IoU beside the thesis's numbers."""
    out = []
    for key, title, unit, factor in (
        ("height", "Table 4.1: height", "cm", 100.0),
        ("rim_radius", "Table 4.2: rim radius", "cm", 100.0),
        ("volume", "Table 4.3: volume (cavity below the rim)", "ml", 1e6),
        ("volume_convex_hull", "Table 4.3: volume (convex hull, thesis 5.1)", "ml", 1e6),
    ):
        out.append(f"### {title}\n")
        header = ["object", f"real {unit}", f"thesis {unit}", "thesis error",
                  f"thesis method {unit}", "error", f"best {unit}", "error"]  # fmt: skip
        rows = []
        errs = np.zeros(3)
        for name, by_method in reports.items():
            t = by_method["thesis"]["tables"][key]
            b = by_method["best"]["tables"][key]
            errs += [t["thesis_rel_error"], t["rel_error"], b["rel_error"]]
            rows.append([
                name, f"{t['real'] * factor:.2f}", f"{t['thesis_computed'] * factor:.2f}",
                f"{t['thesis_rel_error']:.1%}", f"{t['computed'] * factor:.2f}",
                f"{t['rel_error']:.1%}", f"{b['computed'] * factor:.2f}", f"{b['rel_error']:.1%}",
            ])  # fmt: skip
        m = errs / len(reports)
        rows.append(["**mean**", "", "", f"**{m[0]:.1%}**", "", f"**{m[1]:.1%}**", "",
                     f"**{m[2]:.1%}**"])  # fmt: skip
        out.append(markdown_table(header, rows) + "\n")
    out.append("### Per-part IoU against ground truth (thesis method / best)\n")
    rows = []
    for name, by_method in reports.items():
        cells = []
        for part in ("rim", "handle", "container", "outside"):
            pair = (by_method["thesis"]["iou"][part], by_method["best"]["iou"][part])
            cells.append(" / ".join("-" if v is None else f"{v:.2f}" for v in pair))
        rows.append([name, *cells])
    out.append(markdown_table(["object", "rim", "handle", "container", "outside"], rows))
    return "\n".join(out)
