#!/usr/bin/python3
"""The figures of docs/research/thesis.md, drawn from the committed tables only.

Developer script (Debian's python3-matplotlib 3.6; the `uplvsm` binary never needs it). It reads each study folder's
table.csv (every run), stats.csv (every mean, difference and gain with its interval, written by the study's report in
C++: study/grid_stats.h), curves.csv (held-out PSNR during training) and the paper's cells
(docs/research/data/paper_*_scaling.csv), and writes SVG with text kept as text into docs/research/thesis/figures/.

    /usr/bin/python3 tools/thesis/plot_thesis.py            # every figure whose tables exist
    /usr/bin/python3 tools/thesis/plot_thesis.py --png DIR  # also a PNG of each, to look at

One style per model in every figure: colour and marker name the model (UP-LVSM blue circle, PT-LVSM green square,
LVSM red triangle); the line and the marker's fill name the cameras it trained with (solid and filled: exact, or
none read; dashed and open: with pose noise or SfM's), and the paper's numbers are dotted. A series never mixes seed counts: each seed is its own thin line, and the mean
of the seeds with its 95 % bootstrap interval is drawn only where two or more seeds ran.
"""
import argparse
import csv
import math
import pathlib
import sys

import matplotlib

matplotlib.use("svg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402

REPO = pathlib.Path(__file__).resolve().parents[2]
MODELS = {  # the paper's names and one style each
    "uplvsm": dict(name="UP-LVSM", color="#1f5fa8", marker="o"),
    "ptlvsm": dict(name="PT-LVSM", color="#2e8b3a", marker="s"),
    "lvsm": dict(name="LVSM", color="#c0392b", marker="^"),
}
LINES = {"exact": "-", "noisy": "--", "paper": ":"}


def setup():
    plt.rcParams.update({
        "font.family": "DejaVu Sans", "font.size": 9, "axes.titlesize": 9.5, "legend.fontsize": 8,
        "svg.fonttype": "none",  # text stays text: real fonts, selectable, scaled by the reader's viewer
        "svg.hashsalt": "uplvsm-thesis",  # the same tables give the same file
        "axes.spines.top": False, "axes.spines.right": False, "axes.grid": True, "grid.alpha": 0.25,
    })


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def number(text):
    return float(text) if text not in ("", None) else math.nan


class Study:
    """One study folder: its runs (table.csv), statistics (stats.csv) and curves (curves.csv)."""

    def __init__(self, folder):
        self.folder = folder
        self.runs = [dict(r, x=float(r["x"]), seed=int(r["seed"]), psnr=float(r["psnr"]))
                     for r in read_csv(folder / "table.csv")]
        self.stats = read_csv(folder / "stats.csv") if (folder / "stats.csv").exists() else []
        curves = folder / "curves.csv"
        self.curves = read_csv(curves) if curves.exists() else []

    def models(self):
        return list(dict.fromkeys(r["series"] for r in self.runs))

    def seeds(self, model):
        return sorted({r["seed"] for r in self.runs if r["series"] == model})

    def seed_points(self, model, seed):
        pts = sorted((r["x"], r["psnr"]) for r in self.runs if r["series"] == model and r["seed"] == seed)
        return [p[0] for p in pts], [p[1] for p in pts]

    def stat(self, statistic, series, setting="", other="", metric="psnr"):
        for s in self.stats:
            if (s["statistic"], s["series"], s["setting"], s["other"], s["metric"]) == (
                    statistic, series, setting, other, metric):
                return dict(est=number(s["estimate"]), lo=number(s["lo"]), hi=number(s["hi"]),
                            seeds=int(s["seeds"]), scenes=int(s["scenes"]), resampled=s["resampled"])
        return None

    def means(self, model):
        """(x, mean, lo, hi) of the cells two or more seeds ran."""
        out = []
        for s in self.stats:
            if s["statistic"] == "mean" and s["series"] == model and s["metric"] == "psnr" and int(s["seeds"]) > 1:
                out.append((float(s["x"]), number(s["estimate"]), number(s["lo"]), number(s["hi"])))
        return sorted(out)


def paper_cells(name):
    rows = read_csv(REPO / "docs/research/data" / f"paper_{name}_scaling.csv")
    out = {}
    for r in rows:
        out.setdefault(r["series"], []).append(float(r["psnr"]))
    return out


def model_line(ax, model, xs, ys, cameras, label=None, thin=False, paper=False):
    """cameras: "exact" (or none read: UP-LVSM) fills the marker, "noisy" leaves it open; the paper's are dotted."""
    st = MODELS[model]
    filled = cameras == "exact" or model == "uplvsm"
    ax.plot(xs, ys, LINES["paper" if paper else cameras], color=st["color"], marker=st["marker"], label=label,
            lw=0.8 if thin else 1.6, ms=3.5 if thin else 6.5, alpha=0.55 if thin else 1.0,
            mfc=st["color"] if filled else "white", mec=st["color"], mew=1.2)


def mean_with_interval(ax, model, means, cameras, x_of=lambda x: x):
    st = MODELS[model]
    for x, m, lo, hi in means:
        err = [[m - lo], [hi - m]] if not math.isnan(lo) else None
        ax.errorbar([x_of(x)], [m], yerr=err, color=st["color"], marker=st["marker"], ms=7, capsize=3, lw=1.4,
                    mfc=st["color"] if cameras == "exact" else "white", mec="black", mew=0.6, zorder=5)


def seeds_and_means(ax, study, model, cameras, label):
    for i, seed in enumerate(study.seeds(model)):
        xs, ys = study.seed_points(model, seed)
        model_line(ax, model, xs, ys, cameras, label=label if i == 0 else None, thin=True)
    mean_with_interval(ax, model, study.means(model), cameras)


def rooms_axis(ax, xs):
    ax.set_xscale("log", base=4)
    ax.set_xticks(sorted(set(xs)))
    ax.set_xticklabels([f"{x:g}" for x in sorted(set(xs))])
    ax.minorticks_off()
    ax.set_xlabel("training rooms (log scale, 4x apart)")


def delta_panel(ax, arms, paper, paper_cameras, paper_label):
    """PSNR change from the smallest subset against 4x steps of data: every seed of ours and the paper's cells."""
    for study, model, cameras in arms:
        x0 = min(r["x"] for r in study.runs if r["series"] == model)
        for i, seed in enumerate(study.seeds(model)):
            xs, ys = study.seed_points(model, seed)
            if not xs or xs[0] != x0:
                continue
            model_line(ax, model, [math.log(x / x0, 4) for x in xs], [y - ys[0] for y in ys], cameras,
                       label=f"ours, {MODELS[model]['name']}" if i == 0 else None, thin=True)
    for model, ys in paper.items():
        if model in MODELS:
            model_line(ax, model, list(range(len(ys))), [y - ys[0] for y in ys], paper_cameras,
                       label=f"paper, {MODELS[model]['name']}", paper=True)
    ax.axhline(0, color="0.4", lw=0.6)
    ax.xaxis.set_major_locator(matplotlib.ticker.MultipleLocator(1))
    ax.set_xlabel("4x steps of training data from the smallest subset")
    ax.set_ylabel("PSNR change from the smallest subset (dB)")
    ax.set_title(paper_label)
    ax.legend(loc="upper left", ncol=2, frameon=False)


def scaling_figure(arms, paper, paper_cameras, title, paper_title):
    """(a) our PSNR against training rooms, (b) the change from the smallest subset beside the paper's."""
    fig, (a, b) = plt.subplots(1, 2, figsize=(10.5, 4.2), constrained_layout=True)
    xs = []
    for study, model, cameras in arms:
        label = f"{MODELS[model]['name']}" + ("" if cameras == "exact" else f", {study.noise_label}")
        seeds_and_means(a, study, model, cameras, label)
        xs += [r["x"] for r in study.runs if r["series"] == model]
    rooms_axis(a, xs)
    a.set_ylabel("PSNR on the test rooms (dB)")
    a.set_title("(a) ours: a thin line per seed; a large marker the seeds' mean\nwith its 95 % bootstrap interval (where two or more seeds ran)")
    a.legend(loc="best", frameon=False)
    delta_panel(b, arms, paper, paper_cameras, "(b) " + paper_title)
    fig.suptitle(title, fontsize=10.5)
    return fig


def broken_sigma_axes(fig, spec):
    """A narrow panel for sigma = 0 and a log panel for sigma > 0, sharing y, with break marks between them."""
    zero, logx = fig.add_subplot(spec[0]), None
    logx = fig.add_subplot(spec[1], sharey=zero)
    logx.set_xscale("log")
    zero.set_xlim(-0.5, 0.5)
    zero.set_xticks([0])
    zero.spines["right"].set_visible(False)
    logx.spines["left"].set_visible(False)
    logx.tick_params(left=False, labelleft=False)
    kw = dict(marker=[(-1, -1.5), (1, 1.5)], markersize=9, linestyle="none", color="k", mec="k", mew=1,
              clip_on=False)
    zero.plot([1], [0], transform=zero.transAxes, **kw)
    logx.plot([0], [0], transform=logx.transAxes, **kw)
    return zero, logx


def pose_noise_figure(study):
    fig = plt.figure(figsize=(7.5, 4.2), constrained_layout=True)
    zero, logx = broken_sigma_axes(fig, fig.add_gridspec(1, 2, width_ratios=[1, 7]))
    levels = sorted({r["x"] for r in study.runs})
    for model in study.models():
        noisy = "exact" if model == "uplvsm" else "noisy"  # at sigma 0 every model trained on exact cameras
        for i, seed in enumerate(study.seeds(model)):
            xs, ys = study.seed_points(model, seed)
            label = MODELS[model]["name"] + (" (reads no camera: one run per seed)" if model == "uplvsm" else "")
            for ax, keep, cameras in ((zero, lambda x: x == 0, "exact"), (logx, lambda x: x > 0, noisy)):
                pts = [(x, y) for x, y in zip(xs, ys) if keep(x)]
                model_line(ax, model, [p[0] for p in pts], [p[1] for p in pts], cameras,
                           label=label if (i == 0 and ax is logx) else None, thin=True)
        means = study.means(model)
        mean_with_interval(zero, model, [m for m in means if m[0] == 0], "exact")
        mean_with_interval(logx, model, [m for m in means if m[0] > 0], noisy)
    logx.axvline(0.01, color="0.3", lw=0.8, ls=":")
    logx.text(0.0105, logx.get_ylim()[1], " SfM-like: 1.8° rotation,\n 1.6 % translation per camera",
              va="top", fontsize=7.5, color="0.25")
    logx.set_xticks([x for x in levels if x > 0])
    logx.set_xticklabels([f"{x:.3g}" for x in levels if x > 0])
    logx.minorticks_off()
    logx.set_xlabel("σ of the noise on the training cameras' (t, q) encoding (log scale; 0 left of the break)")
    zero.set_ylabel("PSNR on the 48 test rooms (dB)")
    logx.legend(loc="lower left", frameon=False)
    fig.suptitle("Pose noise on the training cameras: tiny, 400 rooms, 4000 steps, scored with exact test cameras",
                 fontsize=10.5)
    return fig


def paper_gain(ys):
    """The paper's Avg. Gain from its cells: the least-squares slope over its 4x rungs (study/scaling_gain.h; the C++
    test asserts the printed values from the same cells)."""
    n = len(ys)
    mx, my = (n - 1) / 2, sum(ys) / n
    return sum((i - mx) * (y - my) for i, y in enumerate(ys)) / sum((i - mx) ** 2 for i in range(n))


def dot_rows(ax, rows, title):
    """One row per (group, model): the gain, its 95 % interval where there is one."""
    labels = []
    for i, (group, model, cameras, est, lo, hi) in enumerate(rows):
        st = MODELS[model]
        err = [[est - lo], [hi - est]] if not math.isnan(lo) else None
        ax.errorbar([est], [i], xerr=err, color=st["color"], marker=st["marker"], ms=6.5, capsize=3, lw=1.4,
                    mfc=st["color"] if cameras == "exact" else "white", mec=st["color"], mew=1.2)
        labels.append(f"{group}: {st['name']}")
    ax.set_yticks(range(len(rows)))
    ax.set_yticklabels(labels)
    ax.invert_yaxis()
    ax.axvline(0, color="0.4", lw=0.6)
    ax.set_xlabel("PSNR gain per 4x training data (dB)")
    ax.set_title(title)


def our_gain_rows(entries):
    """entries: (group, study or {model: study}, models, cameras)."""
    rows = []
    for group, study, models, cameras in entries:
        for model in models:
            s = study.stat("gain", model) if isinstance(study, Study) else study[model].stat("gain", model)
            if s and not math.isnan(s["est"]):
                rows.append((group, model, cameras if model != "uplvsm" else "exact", s["est"], s["lo"], s["hi"]))
    return rows


def gains_figure(entries):
    paper_rows = []
    for name, group, cameras in (("objaverse", "Objaverse, exact cameras", "exact"),
                                 ("re10k", "RealEstate10K, SfM cameras", "noisy")):
        for model, ys in paper_cells(name).items():
            style = "exact" if model == "uplvsm" else cameras  # UP-LVSM reads no camera: always filled
            paper_rows.append((group, model, style, paper_gain(ys), math.nan, math.nan))
    ours = our_gain_rows(entries)
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 0.32 * max(len(ours), 6) + 1.6), constrained_layout=True)
    dot_rows(a, paper_rows, "the paper (one run per cell: no interval)")
    dot_rows(b, ours, "ours, tiny: 95 % bootstrap interval\n(two seeds: their range; one seed: none)")
    fig.suptitle("The paper's Avg. Gain (least-squares slope over every subset), the paper's and ours",
                 fontsize=10.5)
    return fig


def curves_figure(study, title, cameras="exact"):
    models = [m for m in MODELS if any(c["series"] == m for c in study.curves)]
    fig, axes = plt.subplots(1, len(models), figsize=(3.9 * len(models), 3.6), sharey=True, constrained_layout=True)
    axes = axes if len(models) > 1 else [axes]
    settings = list(dict.fromkeys(c["setting"] for c in study.curves))
    for ax, model in zip(axes, models):
        for k, setting in enumerate(settings):
            shade = 0.25 + 0.75 * (k + 1) / len(settings)  # darker: more rooms
            seeds = sorted({c["seed"] for c in study.curves if c["series"] == model and c["setting"] == setting})
            for j, seed in enumerate(seeds):
                pts = [(float(c["step"]), float(c["psnr"])) for c in study.curves
                       if c["series"] == model and c["setting"] == setting and c["seed"] == seed]
                label = setting.replace("scenes", "rooms") + (f" ({len(seeds)} seeds)" if len(seeds) > 1 else "")
                ax.plot([p[0] for p in pts], [p[1] for p in pts], LINES[cameras], color=MODELS[model]["color"],
                        alpha=shade, lw=1.2, label=label if j == 0 else None)
        ax.set_title(MODELS[model]["name"])
        ax.set_xlabel("training step")
        ax.legend(loc="lower right", frameon=False, fontsize=7)
    axes[0].set_ylabel("held-out PSNR, 16 test rooms (dB)")
    fig.suptitle(title, fontsize=10.5)
    return fig


def save(fig, out, name, png_dir):
    out.mkdir(parents=True, exist_ok=True)
    fig.savefig(out / f"{name}.svg", metadata={"Date": None})
    if png_dir:
        pathlib.Path(png_dir).mkdir(parents=True, exist_ok=True)
        fig.savefig(pathlib.Path(png_dir) / f"{name}.png", dpi=110)
    plt.close(fig)
    print(f"-> {out / name}.svg")


def load(thesis, folder, noise_label=""):
    path = thesis / folder
    if not (path / "table.csv").exists():
        return None
    study = Study(path)
    study.noise_label = noise_label
    return study


def issue72_figures(thesis, out, png):
    exact, noisy = load(thesis, "scaling"), load(thesis, "scaling_noise0.1", "σ 0.1")
    budget, noise = load(thesis, "scaling_budget16000"), load(thesis, "pose_noise")
    save(pose_noise_figure(noise), out, "pose_noise", png)
    arms = [(exact, m, "exact") for m in ("uplvsm", "ptlvsm", "lvsm")]
    save(scaling_figure(arms, paper_cells("objaverse"), "exact",
                        "Exact cameras: tiny on 125-8000 rooms, 8000 steps each (issue 72; superseded initialisation)",
                        "change with data: ours and the paper's\nObjaverse table (exact cameras), on one axis"),
         out, "scaling_exact", png)
    arms = [(exact, "uplvsm", "exact"), (noisy, "ptlvsm", "noisy"), (noisy, "lvsm", "noisy")]
    save(scaling_figure(arms, paper_cells("re10k"), "noisy",
                        "Posed models with σ 0.1 pose noise, UP-LVSM (reads no camera) beside them: 8000 steps",
                        "change with data: ours and the paper's\nRealEstate10K table (SfM cameras), on one axis"),
         out, "scaling_noise0.1", png)
    save(gains_figure([("exact, 8000 steps", exact, ["uplvsm", "ptlvsm", "lvsm"], "exact"),
                       ("exact, 16000 steps", budget, ["uplvsm", "lvsm"], "exact"),
                       ("σ 0.1, 8000 steps", {"uplvsm": exact, "ptlvsm": noisy, "lvsm": noisy},
                        ["uplvsm", "ptlvsm", "lvsm"], "noisy")]), out, "gains", png)
    for study, name, title, cameras in (
            (exact, "curves_exact", "Held-out PSNR during training: exact cameras, 8000 steps", "exact"),
            (noisy, "curves_noise0.1", "Held-out PSNR during training: σ 0.1 pose noise, 8000 steps", "noisy"),
            (budget, "curves_budget16000", "Held-out PSNR during training: exact cameras, 16000 steps", "exact")):
        save(curves_figure(study, title, cameras), out, name, png)


def sfm_figures(thesis, out, png):
    """The study of issue 83 (tools/thesis/run_tiny.sh sfm-*), once its tables are committed."""
    exact, noisy = load(thesis, "sfm_exact"), load(thesis, "sfm_noise0.01", "σ 0.01")
    if not exact or not noisy:
        print("sfm_exact / sfm_noise0.01: not run yet, no figure")
        return
    arms = [(exact, m, "exact") for m in exact.models()] + [(noisy, m, "noisy") for m in noisy.models()]
    save(scaling_figure(arms, paper_cells("re10k"), "noisy",
                        "Exact cameras and SfM-like pose noise (σ 0.01), UP-LVSM beside the posed models",
                        "change with data: ours and the paper's\nRealEstate10K table (SfM cameras), on one axis"),
         out, "sfm_scaling", png)
    with_up = dict({m: noisy for m in noisy.models()}, uplvsm=exact)  # UP-LVSM reads no camera: its runs stand
    save(gains_figure([("exact", exact, exact.models(), "exact"),
                       ("σ 0.01", with_up, ["uplvsm"] + noisy.models(), "noisy")]), out, "sfm_gains", png)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--thesis", default=str(REPO / "docs/research/thesis"), help="the committed study folders")
    p.add_argument("--out", default=None, help="where the SVGs go (default: <thesis>/figures)")
    p.add_argument("--png", default=None, help="also write a PNG of each figure here (to look at them)")
    a = p.parse_args()
    thesis = pathlib.Path(a.thesis)
    out = pathlib.Path(a.out) if a.out else thesis / "figures"
    setup()
    issue72_figures(thesis, out, a.png)
    sfm_figures(thesis, out, a.png)
    return 0


if __name__ == "__main__":
    sys.exit(main())
