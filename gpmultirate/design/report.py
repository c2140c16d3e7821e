"""The files of ``gpmultirate design``: the designed input, its figure and a summary.

:func:`design_files` designs the input from a pilot model and returns the
files' contents (``input.csv``, ``bands.png``, ``summary.md``,
``summary.json``) for :func:`gpmultirate.io.write_folder`.
"""

from __future__ import annotations

import io
import json

import numpy as np

from gpmultirate.design.bands import band_decibels, band_radius
from gpmultirate.design.confounding import confounded_frequencies
from gpmultirate.design.figure import design_figure
from gpmultirate.design.multisine import design_multisine, flat_multisine
from gpmultirate.design.predicted import predicted_frequency_response
from gpmultirate.design.prior import design_prior

__all__ = ["DESIGN_FILES", "design_files"]

#: the files :func:`design_files` returns
DESIGN_FILES = ("input.csv", "bands.png", "summary.md", "summary.json")


def _summary_of(frf, freqs_mask, magnitude):
    radius = band_radius(frf)[freqs_mask]
    above = frf.freqs[freqs_mask] > frf.slow_nyquist
    out = {"mean_band_radius": float(radius.mean()), "worst_band_radius": float(radius.max()),
           "mean_band_radius_above_slow_nyquist":
               float(radius[above].mean()) if np.any(above) else None}
    if magnitude is not None:
        db = band_decibels(radius, magnitude[freqs_mask])
        out["mean_band_db"], out["worst_band_db"] = float(np.mean(db)), float(np.max(db))
    return out


def design_files(model, band_hz, *, n_samples=None, factor=None, offset=0, rms=1.0,
                 criterion="mean", relative=False, floor=0.5, random_state=0, given_input=None,
                 source="model") -> tuple[dict, dict]:
    """Design an input from a pilot model and return the files of the result.

    Parameters
    ----------
    model : FIRGaussianProcess (fitted)
        The pilot model.
    band_hz : (f_lo, f_hi)
    n_samples : int, optional
        Record length; default the pilot's.
    factor : int, optional
        Default the pilot's downsampling factor.
    offset, rms, criterion, relative, floor, random_state
        As for :func:`~gpmultirate.design.design_multisine`.
    given_input : ndarray, optional
        The input to compare with (the "before"); default a flat random-phase
        multisine over ``band_hz`` at the same rms.
    source : str
        The pilot model's file, for the summary.

    Returns
    -------
    files : dict of str to bytes
    summary : dict
        The content of ``summary.json``.
    """
    prior = design_prior(model)
    T = prior.sample_time
    n_samples = int(model.observation_.n_samples) if n_samples is None else int(n_samples)
    factor = int(model.observation_.slow_factor) if factor is None else int(factor)
    u, design = design_multisine(prior, n_samples, factor, band_hz, rms,
                                 random_state=random_state, criterion=criterion,
                                 offset=offset, relative=relative, floor=floor,
                                 return_design=True)
    if given_input is None:
        before_input = flat_multisine(n_samples, band_hz, rms, T, random_state=random_state)
        before_name = "flat random-phase multisine over the range"
    else:
        before_input = np.asarray(given_input, dtype=float)
        before_name = "the given input"
    freqs = np.fft.rfftfreq(2 * n_samples, d=T)
    before = predicted_frequency_response(prior, before_input, factor, offset, freqs=freqs)
    after = predicted_frequency_response(prior, u, factor, offset, freqs=freqs)
    pilot = model.frequency_response(freqs, sample_time=T)
    inside = (freqs >= band_hz[0]) & (freqs <= band_hz[1])
    summary = {
        "pilot_model": source,
        "band_hz": [float(band_hz[0]), float(band_hz[1])],
        "n_samples": n_samples, "sample_time": T, "factor": factor,
        "offset": offset if np.ndim(offset) == 0 else list(offset),
        "slow_nyquist_hz": after.slow_nyquist, "rms": rms, "criterion": criterion,
        "relative": bool(relative), "floor": floor, "noise_level": prior.noise_level,
        "before_input": before_name,
        "before": _summary_of(before, inside, pilot.magnitude),
        "designed": _summary_of(after, inside, pilot.magnitude),
        "excited_bins": int(np.sum(design.amplitudes > 0)),
        "candidate_bins": int(design.amplitudes.shape[0]),
        "confounded_groups_before": len(confounded_frequencies(before_input, factor, T).groups),
        "confounded_groups_designed": len(design.confounding.groups),
        "design_seconds": design.seconds,
    }
    summary["narrowing_mean"] = (summary["before"]["mean_band_radius"]
                                 / summary["designed"]["mean_band_radius"])
    figure = design_figure(before, after, band_hz, reference=pilot)
    png = io.BytesIO()
    figure.savefig(png, format="png", dpi=150)
    time = np.arange(n_samples) * T
    csv = "index,time,u\n" + "".join(f"{i},{t:.10g},{v:.17g}\n"
                                      for i, (t, v) in enumerate(zip(time, u)))
    files = {"input.csv": csv.encode("utf-8"), "bands.png": png.getvalue(),
             "summary.md": _markdown(summary).encode("utf-8"),
             "summary.json": (json.dumps(summary, indent=2) + "\n").encode("utf-8")}
    return files, summary


def _markdown(summary: dict) -> str:
    lo, hi = summary["band_hz"]
    rows = [("mean band radius", "mean_band_radius"), ("worst band radius", "worst_band_radius"),
            ("mean band radius above slow Nyquist", "mean_band_radius_above_slow_nyquist"),
            ("mean band (dB)", "mean_band_db"), ("worst band (dB)", "worst_band_db")]
    lines = [
        "# Experiment design", "",
        f"Pilot model `{summary['pilot_model']}`; range {lo:g}..{hi:g} Hz; "
        f"{summary['n_samples']} fast samples of {summary['sample_time']:g} s, factor "
        f"{summary['factor']} (slow Nyquist {summary['slow_nyquist_hz']:g} Hz); input rms "
        f"{summary['rms']:g}; criterion {summary['criterion']}"
        + (" (relative to the pilot's |G|)" if summary["relative"] else "") + ".", "",
        "Predicted 95 % bands over the range, for any output record, with the pilot's "
        "hyperparameters held fixed:", "",
        f"| | before ({summary['before_input']}) | designed |", "|---|---:|---:|",
    ]
    for label, key in rows:
        b, d = summary["before"].get(key), summary["designed"].get(key)
        if b is not None and d is not None:
            lines.append(f"| {label} | {b:.4g} | {d:.4g} |")
    lines += ["", f"The designed input narrows the mean band {summary['narrowing_mean']:.2f} "
              f"times; it excites {summary['excited_bins']} of {summary['candidate_bins']} "
              f"bins, in {summary['confounded_groups_designed']} groups that alias onto each "
              f"other at the slow rate (before: {summary['confounded_groups_before']}).", ""]
    return "\n".join(lines)
