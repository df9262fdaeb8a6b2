"""Maps of where each relation holds: one PNG per experiment, one panel per relation, every
point of the sweep drawn over the spec's two map axes (green holds, red does not, grey could
not be checked; a relation checked at no point is left out). Grid points are squares, Monte
Carlo samples dots; with more than two parameters the map is a projection (the other
parameters vary at each drawn point)."""

from __future__ import annotations

import math
import textwrap
from collections.abc import Sequence
from pathlib import Path

from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from hil.output.plots import save_figure
from hil.sweep.relations import PointRelation, RelationFraction

COLOURS = {True: "tab:green", False: "tab:red", None: "0.7"}
LABELS = {True: "holds", False: "does not hold", None: "not checked"}


def _coordinate(value: object, categories: list[str]) -> float:
    if isinstance(value, int | float) and not isinstance(value, bool):
        return float(value)
    text = str(value)
    if text not in categories:
        categories.append(text)
    return float(categories.index(text))


def _panel(ax, items: Sequence[PointRelation], axes: Sequence[str], grid: bool) -> None:
    x_categories: list[str] = []
    y_categories: list[str] = []
    for verdict in (None, False, True):
        chosen = [i for i in items if i.relation.holds is verdict]
        if not chosen:
            continue
        xs = [_coordinate(i.values.get(axes[0]), x_categories) for i in chosen]
        ys = (
            [_coordinate(i.values.get(axes[1]), y_categories) for i in chosen]
            if len(axes) > 1
            else [0.0] * len(chosen)
        )
        ax.scatter(
            xs, ys, c=COLOURS[verdict], marker="s" if grid else "o", s=60 if grid else 18,
            edgecolors="none", alpha=0.9,
        )  # fmt: skip
    for categories, set_ticks in ((x_categories, ax.set_xticks), (y_categories, ax.set_yticks)):
        if categories:
            set_ticks(range(len(categories)), categories)
    ax.set_xlabel(axes[0])
    if len(axes) > 1:
        ax.set_ylabel(axes[1])
    else:
        ax.set_yticks([])
    ax.grid(True, alpha=0.3)


def write_maps(
    out_dir: Path,
    found: Sequence[PointRelation],
    fractions: Sequence[RelationFraction],
    axes: Sequence[str],
    *,
    grid: bool,
    title: str,
) -> list[Path]:
    """maps/<experiment>.png for every experiment with relations; the paths written."""
    folder = Path(out_dir) / "maps"
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for experiment in dict.fromkeys(f.experiment for f in fractions if f.checked):
        mine = [f for f in fractions if f.experiment == experiment and f.checked]
        columns = min(3, len(mine))
        rows = math.ceil(len(mine) / columns)
        figure = Figure(figsize=(5.2 * columns, 4.4 * rows + 0.8), layout="constrained")
        panels = figure.subplots(rows, columns, squeeze=False).ravel()
        figure.suptitle(f"{title}: {experiment}", fontsize=11)
        for ax, fraction in zip(panels, mine, strict=False):
            items = [i for i in found if i.key == (experiment, fraction.claim)]
            _panel(ax, items, axes, grid)
            share = "-" if fraction.fraction is None else f"{100 * fraction.fraction:.0f} %"
            ax.set_title(
                "\n".join(textwrap.wrap(fraction.claim, 48)) + f"\nholds at {share} of "
                f"{fraction.checked} checked points",
                fontsize=8,
            )
        for ax in panels[len(mine) :]:
            ax.set_visible(False)
        handles = [
            Line2D([], [], marker="s" if grid else "o", ls="", color=COLOURS[v], label=LABELS[v])
            for v in (True, False, None)
        ]
        figure.legend(handles=handles, loc="outside lower center", ncols=3, fontsize=8)
        paths.append(save_figure(figure, folder / f"{experiment}.png"))
    return paths
