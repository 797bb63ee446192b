"""The study's outputs in words: the findings, results.md, and the faithful study's tables.

The prose lives here, chosen from the numbers of :mod:`.findings`: each sentence of evidence
and each likely reason is written only when the numbers it cites support it. The figures are
:mod:`.figures`.
"""

from __future__ import annotations

import numpy as np

from ...sim.trajectories import STUDY_JOINTS_DEG
from .findings import BLACK_BOXES, Finding
from .layout import AXES, DATASETS, FEATURES, FIGURES, METHODS, TABLE2_TOLERANCE

METHOD_LABELS = {"rf": "RF", "svr": "SVR", "svr_scaled": "SVR, scaled targets",
                 "hybrid": "hybrid (physics + RF)", "physics": "physics"}
CLAIMS = {
    "a": "RF has a lower test MSE than SVR on every axis",
    "b": "RF is ~unchanged when q̇, q̈ are added, SVR changes",
    "c": "Fz and Tz are the worst axes on the reference trajectory",
    "d": "The RF Fx model relies on the joint positions q",
    "e": "More Z motion makes Fz and Tz easier to learn (the study's explanation of c)",
    "f": "Physics + RF residual beats the best tuned RF or SVR on every axis",
}
#: Below this σ²/var an axis "varies well above the noise" (its std is over ~3 σ).
WELL_ABOVE_NOISE = 0.1


# ----------------------------------------------------------------------------------------------
# Findings in words.
# ----------------------------------------------------------------------------------------------
def finding_records(found: list[Finding]) -> list[dict]:
    """results.json's findings: each :class:`Finding` with its claim, evidence and likely
    reason (``why``: None when reproduced, or when the numbers support no reason)."""
    by_id = {f.id: f for f in found}
    records = []
    for f in found:
        evidence, why = describe(f, by_id)
        records.append({"id": f.id, "claim": CLAIMS[f.id], "source": f.source,
                        "dataset": f.dataset, "reproduced": f.reproduced,
                        "evidence": evidence, "numbers": f.numbers, "why": why})
    return records


def describe(f: Finding, by_id: dict[str, Finding] | None = None) -> tuple[str, str | None]:
    """(evidence, why) of a finding; `by_id` holds the other findings, for cross-references."""
    evidence, why = _WORDS[f.id](f.numbers, by_id or {f.id: f})
    return evidence, None if f.reproduced else why


def _words_a(n, _by_id):
    total, wins, scaled = n["cells"], n["rf_wins"], n["rf_wins_vs_scaled_svr"]
    losses = [f"{x['axis']} ({x['features']}) {x['rf_mse']:.3g} vs {x['svr_mse']:.3g}"
              for x in n["svr_wins_reference"]]
    evidence = (
        f"RF wins {wins['reference']}/{total} (axis × feature set) cells on reference, "
        f"{wins['z_rich']}/{total} on z_rich; against SVR with scaled targets "
        f"{scaled['reference']}/{total} and {scaled['z_rich']}/{total}"
        + (f"; SVR wins on reference (RF vs SVR MSE) {', '.join(losses)}" if losses else ""))
    shuffled, narrow, eps = n["shuffled_test_over_cv"], n["narrow_axes_std"], n["svr_epsilon"]
    why = ("we test on held-out trajectories, the study on rows of its one trajectory. A new "
           "trajectory asks for interpolation between the training trajectories, where a "
           "forest is piecewise constant and an RBF kernel is smooth")
    if shuffled > 1:
        why += (f"; on rows of the training trajectories (shuffled CV) RF's MSE is "
                f"{shuffled:.0f}× lower than on new ones")
    if narrow and wins["reference"] > 0:
        why += (f". Where RF does win, it is partly the study's unscaled SVR targets: SVR's "
                f"ε = {eps:g} is wider than the whole signal of {', '.join(narrow)} (std "
                + ", ".join(f"{std:.2g}" for std in narrow.values())
                + "), so SVR predicts little more than their mean there")
    return evidence, why


def _words_b(n, _by_id):
    change, axis, limit = n["largest_change"], n["largest_change_axis"], n["threshold"]
    rf, svr = change["reference"]["rf"], change["reference"]["svr"]
    evidence = (
        f"largest change of the variance score from q to q,qd,qdd on reference: RF "
        f"{rf:+.3f} ({axis['reference']['rf']}), SVR {svr:+.3f} ({axis['reference']['svr']}); "
        f"on z_rich RF {change['z_rich']['rf']:+.3f}, SVR {change['z_rich']['svr']:+.3f} "
        f"(unchanged: |change| < {limit})")
    why = []
    if not n["rf_unchanged"] and rf < 0:
        why.append("RF changes (its variance score drops): along a few training trajectories "
                   "q̇ and q̈ are nearly functions of q, so trees split on them as a proxy "
                   "for where on the trajectory they are — splits that do not carry over to "
                   "a new trajectory")
    elif not n["rf_unchanged"]:
        why.append("RF changes (its variance score rises): q̇ and q̈ carry information about "
                   "the wrench that q alone does not")
    if not n["svr_changed"]:
        why.append("SVR barely changes: inputs are scaled to [-1, 1] and the kernel width is "
                   "tuned, so extra weakly relevant columns cost it little")
    return evidence, "; ".join(why) or None


def _words_c(n, _by_id):
    nmse, floor, order = n["mean_nmse"], n["noise_floor_nmse"], n["worst_first"]
    physics = n["physics_nmse"]
    evidence = ("mean NMSE of RF and SVR over the feature sets, worst first: "
                + ", ".join(f"{a} {nmse[a]:.3g}" for a in order))
    worst = order[:2]
    parts = []
    if "Fz" in worst:
        parts.append(f"Fz is hard for the study's reason (σ²/var, the NMSE of a perfect "
                     f"model: Fz {floor['Fz']:.2g})")
    if "Tz" not in worst and floor["Tz"] < WELL_ABOVE_NOISE:
        parts.append(f"{'but ' if parts else ''}our Tz varies well above the noise (σ²/var "
                     f"{floor['Tz']:.2g}; the tool's centre of mass is off the sensor axis)")
    # Worst axes the physics model predicts far better: the data determines them, the black
    # boxes interpolate them poorly between trajectories.
    for a in [a for a in worst if a not in ("Fz", "Tz") and physics[a] < nmse[a]]:
        parts.append(f"{'while ' if parts else ''}the black boxes interpolate {a} poorly "
                     f"between trajectories (the physics model's {a} NMSE is "
                     f"{physics[a]:.2g})")
    why = f"the worst axes here are {worst[0]} and {worst[1]}"
    if parts:
        why += ". " + _capitalised(", ".join(parts))
    return evidence, why


def _words_d(n, by_id):
    share, fx, limit = n["q_share"], n["rf_fx_nmse"], n["threshold"]
    evidence = (
        f"q holds {share['reference']:.0%} of the Fx forest's importance with q,qd,qdd on "
        f"reference ({share['z_rich']:.0%} on z_rich; concentrated: ≥ {limit:.0%}); top 3: "
        f"{', '.join(n['top3'])}; top 3 of the q-only forest: {', '.join(n['top3_q_only'])}")
    nmse = f"RF's Fx NMSE is {fx['q']:.3g} with q and {fx['q,qd,qdd']:.3g} with q,qd,qdd"
    if fx["q,qd,qdd"] >= fx["q"]:
        b = by_id.get("b")
        see_b = (" (see b)" if b is not None and not b.numbers["rf_unchanged"]
                 and b.numbers["largest_change"]["reference"]["rf"] < 0 else "")
        why = ("with few training trajectories q̇ and q̈ stand in for position along a "
               f"trajectory{see_b}, so the forest spends splits on them; they do not help on "
               f"new trajectories: {nmse}")
    else:
        why = f"q̇ and q̈ carry information about Fx that q does not: {nmse}"
    return evidence, why


def _words_e(n, _by_id):
    ref, rich, tip = n["reference"], n["z_rich"], n["tool_tip_z_std_mm"]
    evidence = (
        f"mean NMSE of RF and SVR, reference → z_rich: Fz {ref['Fz']:.3g} → "
        f"{rich['Fz']:.3g}, Tz {ref['Tz']:.3g} → {rich['Tz']:.3g}; tool-tip z std "
        f"{tip['reference']:.0f} → {tip['z_rich']:.0f} mm")
    why = ("z_rich also covers a larger joint space than reference, so its test trajectories "
           "ask for more interpolation")
    return evidence, why


def _words_f(n, _by_id):
    r, z = n["reference"], n["z_rich"]
    evidence = (
        f"hybrid (q,qd,qdd) has the lower test MSE on {r['axes']}/6 axes on reference, median "
        f"{r['median_ratio']:.0f}× lower; on z_rich {z['axes']}/6, "
        f"{z['median_ratio']:.0f}× lower")
    why = None
    if n["excitation_warnings"]["reference"]:
        why = ("the physics part fits poorly where the data excites the payload parameters "
               "poorly (see the warnings)")
    return evidence, why


_WORDS = {"a": _words_a, "b": _words_b, "c": _words_c, "d": _words_d, "e": _words_e,
          "f": _words_f}


def _capitalised(text: str) -> str:
    return text[:1].upper() + text[1:]


# ----------------------------------------------------------------------------------------------
# Outputs.
# ----------------------------------------------------------------------------------------------
def markdown(results: dict) -> str:
    """results.md: settings, findings, CV disagreement, then per-dataset tables."""
    lines = ["# RF vs SVR for F/T compensation — the study repeated in simulation", "",
             _settings_text(results), "", "## Findings", ""]
    found = [Finding.from_dict(r) for r in results["findings"]]
    by_id = {f.id: f for f in found}
    for f in found:
        evidence, why = describe(f, by_id)
        words = ("reproduced", "not reproduced") if f.source == "study" else (
            "holds", "does not hold")
        mark = words[0] if f.reproduced else f"**{words[1]}**"
        source = "" if f.source == "study" else f" ({f.source}'s claim, not the study's)"
        lines.append(f"* ({f.id}) {CLAIMS[f.id]}{source} — {mark}. {_sentence(evidence)}")
        if why:
            lines.append(f"  *Why:* {_sentence(why)}")
    if "study_protocols" in results:
        lines += ["", protocols_markdown(results["study_protocols"]),
                  ("The study's trajectory and tool against its Tables 1–3: "
                   "[study_tool.md](study_tool.md).")]
    lines += ["", "## Grouped vs shuffled CV (RF on q)", "",
              "CV MSE of each fold scheme against the held-out test MSE of the model it "
              + "chose; test/CV ≫ 1 means the CV was optimistic.", "",
              "| dataset | scheme | " + " | ".join(f"{a} CV" for a in AXES)
              + " | median test/CV |", "|---" * (len(AXES) + 3) + "|"]
    for d in DATASETS:
        dis = results["cv_disagreement"][d]
        for scheme in ("grouped", "shuffled"):
            row = dis[scheme]
            lines.append(f"| {d} | {scheme} | " + " | ".join(
                f"{row['cv_mse'][a]:.3g} → {row['test_mse'][a]:.3g}" for a in AXES)
                + f" | {row['median_test_over_cv']:.2f} |")
    lines += ["", "Cells: CV MSE → test MSE (N², (N·m)²).", ""]
    for d in DATASETS:
        lines += _dataset_markdown(results, d)
    lines += ["## Grid sizes", "", "| estimator | " + " | ".join(FEATURES) + " |",
              "|---" * (len(FEATURES) + 1) + "|"]
    for name, sizes in results["grid_sizes"].items():
        lines.append(f"| {name} | " + " | ".join(str(sizes[f]) for f in FEATURES) + " |")
    lines.append("")
    return "\n".join(lines)


def _dataset_markdown(results, d) -> list[str]:
    size, tip = results["sizes"][d], results["tool_tip"][d]
    lines = [f"## Dataset `{d}`", "",
             f"{size['train_rows']} training rows ({size['svr_train_rows']} for SVR) from "
             + f"trajectories {size['train_trajectories']}, {size['cv_groups']} CV groups; "
             + f"{size['test_rows']} test rows from trajectories {size['test_trajectories']}.",
             "", "Tool tip in the world frame (mm; tilt of the tool axis from vertical in °), "
             + "like the study's Table 3:", "", "| | x | y | z | tilt |", "|---|---|---|---|---|"]
    for stat in ("max", "min", "mean", "std"):
        mm = " | ".join(f"{tip[a][stat] * 1000:.0f}" for a in "xyz")
        lines.append(f"| {stat} | {mm} | {np.degrees(tip['tilt'][stat]):.1f} |")
    ws = results["wrench_stats"][d]
    lines += ["", "Measured wrench on the test rows (N, N·m), like the study's Table 2:", "",
              "| | " + " | ".join(AXES) + " |", "|---" * (len(AXES) + 1) + "|"]
    for stat in ("max", "min", "mean", "std"):
        lines.append(f"| {stat} | " + " | ".join(f"{ws[a][stat]:.3g}" for a in AXES) + " |")
    lines += _metric_tables(results["metrics"][d])
    lines += ["", "**Timings** (s; tune = grid search with refit, fit = one refit)", "",
              "| method | features | tune | fit | predict | µs/row |", "|---|---|---|---|---|---|"]
    for method in METHODS:
        for f in FEATURES:
            t = results["timings"][d][method][f]
            lines.append(f"| {METHOD_LABELS[method]} | {f} | {t.get('tune_s', '–')} | "
                         f"{t['fit_s']:.2f} | {t['predict_s']:.3f} | "
                         f"{t['predict_us_per_row']:.1f} |")
    lines += ["", "**Best parameters** (per axis, Fx first)", ""]
    for method in BLACK_BOXES:
        for f in FEATURES:
            params = results["best_params"][d][method][f]
            lines.append(f"* {METHOD_LABELS[method]} {f}: " + "; ".join(
                f"{a} " + ", ".join(f"{k}={v}" for k, v in sorted(params[a].items()))
                for a in AXES))
    figs = ", ".join(f"[{n}]({n}_{d}.png)" for n in FIGURES)
    lines += ["", f"Figures: {figs}.", ""]
    if results["warnings"][d]:
        lines += ["Warnings: " + " / ".join(results["warnings"][d]), ""]
    return lines


def _metric_tables(metrics: dict) -> list[str]:
    """One table per metric: every method × feature set, per axis."""
    lines = []
    for metric, title in (("nmse", "NMSE (MSE / var of the measured wrench)"),
                          ("variance_score", "Variance score"),
                          ("mse", "MSE (N², (N·m)²)"),
                          ("rms_over_noise", "RMS against the true internal wrench / noise σ")):
        lines += ["", f"**{title}**", "", "| method | features | " + " | ".join(AXES) + " |",
                  "|---" * (len(AXES) + 2) + "|"]
        for method in METHODS:
            for f in FEATURES:
                cell = metrics[method][f]
                lines.append(f"| {METHOD_LABELS[method]} | {f} | "
                             + " | ".join(f"{cell[a][metric]:.3g}" for a in AXES) + " |")
    return lines


def _settings_text(results) -> str:
    s = results["settings"]
    return (
        f"Preset `{s['preset']}`, cv `{s['cv']}` ({s['n_splits']} folds × {s['n_repeats']}), "
        f"{s['trajectories']} trajectories × {s['duration_s']:g} s per dataset, the last "
        f"{s['test_trajectories']} held out whole. Training rows at {s['train_hz']:g} Hz, "
        f"test rows at {s['test_hz']:g} Hz; SVR trained on at most {s['svr_max_rows']} rows "
        f"(evenly spaced). SVR is the study's (targets in N, N·m, so its ε = "
        f"{s['svr_epsilon']:g} is in N or N·m); 'SVR, scaled targets' standardises each axis "
        f"first (ε = {s['svr_epsilon']:g} σ of the axis). Inputs: {s['inputs']}. "
        f"Targets: {s['targets']}; "
        f"truth: {s['truth']}. Sensor `{s['sensor_preset']}`, noise σ = "
        f"{_fmt_list(s['noise_std'])} (N, N·m). Wall time "
        f"{results.get('wall_time_s', float('nan')):.0f} s."
    )


def _sentence(text: str) -> str:
    return text[:1].upper() + text[1:] + "."


def _fmt_list(values) -> str:
    return "[" + ", ".join(f"{v:.3g}" for v in values) + "]"


# ----------------------------------------------------------------------------------------------
# The study repeated faithfully: its tables, its protocol and ours.
# ----------------------------------------------------------------------------------------------
PROTOCOL_LABELS = {
    "study": "study's protocol (random rows of one trajectory, shuffled CV)",
    "study_on_new": "the same models on new trajectories",
    "heldout": "ftdrake's protocol (grouped CV, held-out trajectories)",
}
STUDY_CLAIMS = {k: CLAIMS[k] for k in "abcd"}
STUDY_CLAIMS["c"] = "Fz and Tz are the worst axes"


def tool_markdown(joints: dict, sensor: dict, comparison: dict, tip: dict | None = None) -> str:
    """The study's Tables 1 and 2 beside the simulated ``study`` trajectory's."""
    lines = ["# The study's trajectory and tool, simulated", "",
             f"Table 1 (joints, deg, study convention; {joints['rows']} rows at 40 Hz):", "",
             "| | " + " | ".join(f"q{j + 1}" for j in range(7)) + " |", "|---" * 8 + "|"]
    for i, stat in enumerate(("max", "min", "mean")):
        lines.append(f"| study {stat} | " + " | ".join(
            f"{STUDY_JOINTS_DEG[i, j]:.2f}" for j in range(7)) + " |")
        lines.append(f"| sim {stat} | " + " | ".join(
            f"{joints[f'q{j + 1}'][stat]:.2f}" for j in range(7)) + " |")
    lines += ["", ("Table 2 (measured wrench, N and N·m; the study's rows read sorted as min, "
                   "mean, max — its Tx and Ty rows are garbled in print). Tolerance: "
                   f"{TABLE2_TOLERANCE['force']:g} N, {TABLE2_TOLERANCE['torque']:g} N·m."), "",
              ("| axis | study max | sim max | study min | sim min | study mean | sim mean "
               "| sim std | within tolerance |"), "|---" * 9 + "|"]
    for a, row in comparison.items():
        ok = all(row[s]["ok"] for s in row)
        lines.append(f"| {a} | " + " | ".join(
            f"{row[s]['study']:.3g} | {row[s]['sim']:.3g}" for s in ("max", "min", "mean"))
            + f" | {sensor[a]['std']:.3g} | {'yes' if ok else '**no**'} |")
    if tip:
        lines += ["", "Table 3 (tool tip, mm; the study's frame is unknown, so compare ranges):",
                  "", "| | X | Y | Z |", "|---|---|---|---|",
                  "| study range | 524 | 391 | 78 |",
                  "| sim range | " + " | ".join(
                      f"{(tip[a]['max'] - tip[a]['min']) * 1000:.0f}" for a in "xyz") + " |"]
    return "\n".join(lines) + "\n"


def protocols_markdown(sp: dict) -> str:
    """The protocols section: findings per protocol, then NMSE tables per protocol."""
    found, res = sp["findings"], sp["results"]
    protocols = [p for p in PROTOCOL_LABELS if p in found]
    lines = ["## The study's protocol and ftdrake's, on the study's trajectory", "",
             (f"Rows: {res['sizes']['study_rows']} of the study trajectory at 40 Hz; "
              f"{res['sizes']['train_rows']} training rows, {res['sizes']['test_rows']} random "
              f"test rows; held-out: {res['sizes']['heldout_rows']} rows of "
              f"{res['sizes']['heldout_trajectories']} other study trajectories. Search "
              f"`{res['settings']['search']}` over preset `{res['settings']['preset']}`."
              + ("" if res["settings"].get("retune_heldout", True) else
                 " ftdrake's protocol (held-out column) reuses the study protocol's per-axis "
                 "parameters and refits them on rows evenly spaced in time (`--quick`: no "
                 "second, grouped search).")), "",
             "| finding | " + " | ".join(PROTOCOL_LABELS[p] for p in protocols) + " |",
             "|---" * (len(protocols) + 1) + "|"]
    for k, claim in STUDY_CLAIMS.items():
        cells = [_verdict(k, found[p][k]) for p in protocols]
        lines.append(f"| ({k}) {claim} | " + " | ".join(cells) + " |")
    for metric in ("nmse", "mse"):
        lines += ["", f"**{metric.upper()}**", "",
                  "| protocol | method | features | " + " | ".join(AXES) + " |",
                  "|---" * (len(AXES) + 3) + "|"]
        for p in protocols:
            for m, by_f in res["metrics"][p].items():
                for f, cell in by_f.items():
                    lines.append(f"| {p} | {METHOD_LABELS[m]} | {f} | " + " | ".join(
                        f"{cell[a][metric]:.3g}" for a in AXES) + " |")
    return "\n".join(lines) + "\n"


def _verdict(k: str, f: dict) -> str:
    if f["reproduced"] is None:
        return "n/a (" + f["why"] + ")"
    word = "yes" if f["reproduced"] else "**no**"
    if k == "a":
        return f"{word}: RF wins {f['rf_wins']}/{f['cells']} cells"
    if k == "b":
        rf, svr = f["largest_change"]["rf"], f["largest_change"]["svr"]
        return (f"{word}: largest Δ variance score RF {rf['change']:+.3f} ({rf['axis']}), "
                f"SVR {svr['change']:+.3f} ({svr['axis']})")
    if k == "c":
        nmse = f["mean_nmse"]
        return f"{word}: worst " + ", ".join(f"{a} {nmse[a]:.3g}" for a in f["worst_first"][:3])
    return f"{word}: q holds {f['q_share']:.0%}; top {', '.join(f['top3'])}"
