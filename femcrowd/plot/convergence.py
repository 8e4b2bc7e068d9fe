"""Pictures of a convergence study (``femcrowd convergence``): errors against the mesh size and against run time."""

import math

import numpy as np

from ..files import save_figure


def error_plot(path, rows, metrics, x, xlabel, title, slopes=False, reference=None, size=(4.2, 3.6)):
    """One log-log panel per metric (metrics: {metric: its title}), one line per series of the rows, against the
    column x (plus the published reference curves {(method, metric): [(x, error)]}); slopes: lines h^1/2, h."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    ncol = min(len(metrics), 4)
    nrow = -(-len(metrics) // ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(size[0] * ncol, size[1] * nrow + 0.8), squeeze=False)
    series = list(dict.fromkeys(r["series"] for r in rows))
    for ax, metric in zip(axes.flat, metrics):
        for s in series:
            pts = [(r[x], abs(r[metric])) for r in sorted(rows, key=lambda r: r["level"])   # in level order
                   if r["series"] == s and math.isfinite(r[metric]) and r[metric] != 0]
            if pts:
                ax.loglog(*zip(*pts), "o-", label=s)
        if slopes:
            pts = sorted((r[x], abs(r[metric])) for r in rows if math.isfinite(r[metric]) and r[metric] != 0)
            if len(pts) >= 2:
                h = np.array([pts[0][0], pts[-1][0]])
                for order, style in ((0.5, ":"), (1.0, "--")):
                    ax.loglog(h, pts[-1][1] * (h / h[-1]) ** order, "k" + style, lw=0.8, label=f"h^{order:g}")
        for (method, m), pts in (reference or {}).items():
            if m == metric:
                ax.loglog(*zip(*sorted(pts)), "s--", color="0.35" if "DG0" in method else "k", lw=1,
                          ms=4, label=method)
        ax.set_title(metrics[metric], fontsize=9)
        ax.set_xlabel(xlabel, fontsize=8)
        ax.set_ylabel("error", fontsize=8)
        ax.grid(True, which="both", lw=0.3)
        ax.xaxis.set_minor_formatter(matplotlib.ticker.FuncFormatter(_minor_label))
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=6 if size[0] < 5 else 7)
    for ax in list(axes.flat)[len(metrics):]:
        ax.set_visible(False)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)


def _minor_label(x, pos):
    """Label the minor log ticks 2 and 5 of each decade (the others stay unlabelled)."""
    mantissa = x / 10 ** math.floor(math.log10(x) + 1e-9)
    return f"{x:g}" if any(abs(mantissa - m) < 1e-6 for m in (2, 5)) else ""
