"""The picture of a validation (``femcrowd validate``): specific flow through a bottleneck against its width, the
models beside the experiments."""

from ..files import save_figure


def flows_plot(rows, table, labels, published, path):
    """Specific flow against width: each setting's converged values (the table's rows; the runs' rows, its coarser
    meshes or seeds, as small marks; labels: {setting: label}), and the published measured figures (rows of
    experiments.csv) at these widths as grey symbols per source."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FormatStrFormatter, LogLocator, NullFormatter

    widths = [r["width"] for r in table]
    low, high = min(widths) - 0.25, max(widths) + 0.25
    fig, ax = plt.subplots(figsize=(9, 7.5), layout="constrained")
    markers = iter("osD^v<>p*hX")
    published = [r for r in published if r["width_m"] and low <= r["width_m"] <= high and r["kind"] == "measured"]
    for source in dict.fromkeys(r["source"] for r in published):
        mine = [r for r in published if r["source"] == source]
        ax.scatter([r["width_m"] for r in mine], [r["specific_flow"] for r in mine], marker=next(markers),
                   s=24, color="0.6", label=f"{source} {mine[0]['year']}", zorder=1)
    for k, name in enumerate(dict.fromkeys(r["setting"] for r in table)):
        mine = [r for r in table if r["setting"] == name]
        ax.plot([r["width"] for r in mine], [r["specific_flow"] for r in mine], "o-", color=f"C{k}", lw=2,
                label=labels[name], zorder=3)
        runs = [r for r in rows if r["setting"] == name]
        ax.scatter([r["width"] for r in runs], [r["specific_flow"] for r in runs], s=8, color=f"C{k}", alpha=0.5,
                   zorder=2)
    ax.set(xlabel="bottleneck width w (m)", ylabel="specific flow J / w (persons/(m s))", yscale="log",
           xlim=(low, high), title="Flow through a bottleneck: femcrowd (lines) and experiments (grey)")
    ax.yaxis.set_major_locator(LogLocator(subs=(1, 2, 5)))   # 0.5, 1, 2, 5 ... written as plain numbers,
    ax.yaxis.set_major_formatter(FormatStrFormatter("%g"))   # not as 2x10^0
    ax.yaxis.set_minor_formatter(NullFormatter())
    ax.grid(alpha=0.3, which="both")
    fig.legend(loc="outside lower center", fontsize=7.5, ncol=2)
    save_figure(fig, path)
    plt.close(fig)
