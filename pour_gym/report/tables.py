"""Tables: markdown for reports and docs, padded plain text for the terminal."""

from __future__ import annotations

from collections.abc import Sequence


def markdown_table(
    header: Sequence[str], rows: Sequence[Sequence[object]], align: str | None = None
) -> str:
    """A markdown table.

    Args:
        header: the column titles.
        rows: the cells, one sequence per row (formatted with ``str``).
        align: one letter per column, ``l`` (left) or ``r`` (right); default: the first
            column left, the others right (a name, then numbers).

    Raises:
        ValueError: a row or ``align`` of another length than the header.
    """
    n = len(header)
    align = align if align is not None else "l" + "r" * (n - 1)
    if len(align) != n or set(align) - {"l", "r"}:
        raise ValueError(f"align needs one of 'l' or 'r' per column ({n}), not {align!r}")
    rule = "|" + "|".join("---:" if a == "r" else "---" for a in align) + "|"
    lines = ["| " + " | ".join(header) + " |", rule]
    for row in rows:
        if len(row) != n:
            raise ValueError(f"a row has {len(row)} cells, the header {n}: {list(row)}")
        lines.append("| " + " | ".join(str(c) for c in row) + " |")
    return "\n".join(lines)


def text_table(rows: list[list[str]], header: list[str]) -> str:
    """Columns padded to their widest cell, a dashed rule under the header."""
    widths = [max(len(str(r[i])) for r in [header, *rows]) for i in range(len(header))]
    line = "  ".join(f"{{:<{w}}}" for w in widths)
    out = [line.format(*header), line.format(*["-" * w for w in widths])]
    out += [line.format(*map(str, r)) for r in rows]
    return "\n".join(out)
