"""The strategy study's variants in a run's record (report 004, "Pattern Analysis" summary
and Figure 3; docs/esg-options.md): the variants table and Figure 3's curves with their
plot. Like the Figure 2 study (laboratory.esg.study) it needs no measurement, so the plot
child computes and draws it while the rack runs; ``procedures.esg.strategy_variants``
(scipy.optimize) is imported where it is used, never by the run itself."""

from __future__ import annotations

from pathlib import Path

from laboratory.plot_worker import png_options

VARIANTS_RANGE_DEG = 43.0  # the report's rotor: pattern lines end 43 deg from the pole
FIGURE3_RANGES = tuple(range(27, 48))  # top-edge colatitudes (deg), extended to 27
DEFAULT_POINTS = 5000  # orientations averaged (the docs' table)


def variants(points: int = DEFAULT_POINTS) -> dict:
    """The variants table at 43 deg and Figure 3's curves, ``points`` orientations each."""
    from procedures.esg import strategy_variants as sv

    return {"points": points, "range_deg": VARIANTS_RANGE_DEG,
            "table": sv.variants_table(VARIANTS_RANGE_DEG, points),
            "figure3": [sv.figure3(float(r), points) for r in FIGURE3_RANGES]}


def figure3_plot(curves: list[dict], path: Path) -> None:
    """Figure 3: RMS amplification of the cosine pattern against its top edge, mixed and
    all-three curves and the two-pickoff minimum and maximum; extending the range is
    moving left."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 5))
    x = [c["range_deg"] for c in curves]
    for key, label, style in (("mixed", "mixed strategy (RMS)", "-o"),
                              ("all_three", "all three pickoffs (RMS)", "-s"),
                              ("two_min", "two-pickoff minimum", "--v"),
                              ("two_max", "two-pickoff maximum", "--^")):
        pts = [(xi, c[key]) for xi, c in zip(x, curves, strict=True) if c[key] is not None]
        ax.plot([p[0] for p in pts], [p[1] for p in pts], style, ms=4, label=label)
    ax.invert_xaxis()
    ax.set_xlabel("top edge of the cosine pattern, colatitude (deg); range extended "
                  "to the right")
    ax.set_ylabel("amplification of line-edge error (1 sigma)")
    ax.set_title("Report 004 Figure 3: cosine pattern, extended range", y=1.0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110, **png_options())
    plt.close(fig)


def variants_plot(path: Path, points: int = DEFAULT_POINTS) -> dict:
    """The variants, with Figure 3 drawn to ``path``: what the run records of them."""
    got = variants(points)
    figure3_plot(got["figure3"], path)
    return got
