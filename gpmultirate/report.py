"""The report of a fit: its data, model, tuning and validation in JSON and Markdown.

:func:`fit_report` collects what describes a fitted
:class:`~gpmultirate.FIRGaussianProcess` (the data it saw, the tuned kernel
and noise level, the log evidence, the resonances and the order selection
when there were any, the goodness of fit on validation data) into a
:class:`FitReport`.  ``gpmultirate fit`` writes its
:meth:`~FitReport.to_json` and :meth:`~FitReport.to_markdown` as
``summary.json`` and ``summary.md``; :func:`fit_files` gives every file it
writes, :func:`prediction_csv` the table of ``gpmultirate predict``, and
:func:`write_study` the tables of ``gpmultirate demo``.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, field

import numpy as np
from sklearn.utils.validation import check_is_fitted

from gpmultirate.arguments import FIT_KERNELS
from gpmultirate.io import SlowSamples, model_slow_samples
from gpmultirate.units import in_fast_periods

__all__ = ["FIT_KERNELS", "FitReport", "fit_files", "fit_report", "kernel_option",
           "model_slow_samples", "noise_summary", "prediction_csv", "prediction_messages",
           "readings_model",
           "study_header", "write_study"]


def kernel_option(name: str):
    """The ``kernel`` argument of the estimator for ``gpmultirate fit --kernel name``.

    ``dc`` is the estimator's default (``None``), ``auto`` the resonance
    search (``"auto"``); ``tc`` and ``ss`` are ``ConstantKernel(1) * TC()``
    (``SS()``) in the estimator's normalized units, with the default
    kernel's amplitude bounds ``1e-8 .. 1e8``: the estimator scales them to
    each input's data, as it does its default ``dc`` kernel.

    Parameters
    ----------
    name : {"dc", "tc", "ss", "auto"}

    Returns
    -------
    kernel, "auto" or None

    Raises
    ------
    ValueError
        If ``name`` is not one of ``FIT_KERNELS``.

    Examples
    --------
    >>> from gpmultirate.report import kernel_option
    >>> kernel_option("dc") is None, kernel_option("auto")
    (True, 'auto')
    >>> kernel_option("tc")
    1**2 * TC(alpha=0.9)
    """
    from gpmultirate.fitting.prior import kernel_from_name

    if name not in FIT_KERNELS:
        raise ValueError(f"name must be one of {', '.join(FIT_KERNELS)}; got {name!r}")
    return kernel_from_name(name)


def _plain(value):
    """``value`` as JSON-compatible plain Python data (non-finite floats become None)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return value if math.isfinite(value) else None
    if value is None or isinstance(value, str):
        return value
    return str(value)


_ABSENT = object()  # an optional section that is not part of the report


@dataclass(frozen=True)
class FitReport:
    """What describes a fit, as plain data: the sections of ``summary.json``.

    Build it with :func:`fit_report`, or from a ``summary.json`` with
    :meth:`from_dict`.

    Attributes
    ----------
    data : dict
        The data: ``file``, ``inputs``, ``output`` (names), ``n_samples``,
        ``n_slow_samples``, ``sampling`` (a phrase), ``factor``, ``offset``
        (None for irregular instants) and ``sample_time``.
    model : dict
        The estimator, ``order``, ``n_inputs``, ``initial_conditions``,
        ``kernel`` (its text), ``hyperparameters`` (name to value),
        ``tuning``, ``log_evidence``, ``noise_level`` (a variance, in the
        data's units), ``cv_log_predictive`` after cross-validation, and for
        a model whose kernel stays in normalized units
        ``hyperparameter_units`` ``"normalized"`` and ``noise_std`` (in the
        data's units, finite where the variance is beyond the float range);
        for readings interpolated between the ticks ``between_ticks``
        (``route``, ``lags`` and ``estimated_error_noise_std``).
    notes, warnings : tuple of str
        Remarks on the fit, and the warnings it raised.
    resonances : list or None
        The resonances found by ``kernel="auto"``, or None without a search.
    order_selection : dict or None
        ``criterion``, ``orders``, ``score`` and ``best_order`` when the order
        was selected.
    state_space : dict or None
        ``order`` of the state-space model written beside the fit.
    validation : dict or None
        ``file``, ``n_samples``, ``gof_percent`` (eq. 20, ``model.score``)
        and ``fit_percent`` (normalized root-mean-square error) on
        validation data.
    modes : dict or None
        The reduced model's modes with credible intervals and the peaks of
        the frequency response the data support
        (:func:`gpmultirate.modes.modal_analysis`): ``n_states``,
        ``level``, ``n_draws``, ``modes`` and ``peaks`` (lists of dicts),
        ``consistent`` and ``text``.

    Examples
    --------
    >>> from gpmultirate.report import FitReport
    >>> report = FitReport.from_dict({
    ...     "data": {"file": "data.csv", "inputs": ["u"], "output": "y", "n_samples": 90,
    ...              "n_slow_samples": 30, "sampling": "one sample in 3, from row 0",
    ...              "factor": 3, "offset": 0, "sample_time": 0.01},
    ...     "model": {"estimator": "FIRGaussianProcess", "order": 30, "n_inputs": 1,
    ...               "initial_conditions": "zero", "kernel": "DC()",
    ...               "hyperparameters": {}, "tuning": "evidence", "log_evidence": 12.5,
    ...               "noise_level": 0.04},
    ...     "notes": [], "warnings": []})
    >>> print(report.to_markdown().splitlines()[7])
    - noise level (variance): 0.04 (std 0.2)
    >>> FitReport.from_dict(report.to_dict()) == report
    True
    """

    data: dict
    model: dict
    notes: tuple = ()
    warnings: tuple = ()
    resonances: object = field(default=_ABSENT, repr=False)
    order_selection: dict | None = None
    state_space: dict | None = None
    validation: dict | None = None
    modes: dict | None = None

    def to_dict(self) -> dict:
        """The report as JSON-compatible plain data (the content of ``summary.json``).

        Returns
        -------
        dict
            ``data``, ``model``, ``notes``, ``warnings`` and those of
            ``resonances``, ``order_selection``, ``state_space`` and
            ``validation`` that the fit has; non-finite numbers become None.
        """
        out = {"data": self.data, "model": self.model, "notes": list(self.notes),
               "warnings": list(self.warnings)}
        if self.resonances is not _ABSENT:
            out["resonances"] = self.resonances
        for name in ("order_selection", "state_space", "validation", "modes"):
            if getattr(self, name) is not None:
                out[name] = getattr(self, name)
        return _plain(out)

    @property
    def noise_std(self) -> float:
        """The noise standard deviation in the data's units (also for normalized hyperparameters)."""
        std = self.model.get("noise_std")
        return math.sqrt(self.model["noise_level"]) if std is None else float(std)

    def headline(self) -> str:
        """One line: the order, the log evidence, the noise and the validation fit, if any.

        Examples
        --------
        >>> FitReport(data={}, model={"order": 30, "log_evidence": 12.5,
        ...                           "noise_level": 0.04}).headline()
        'order 30, log evidence 12.5, noise std 0.2'
        """
        line = (f"order {self.model['order']}, log evidence "
                f"{self.model['log_evidence']:.6g}, noise std {self.noise_std:.4g}")
        noise = self.model.get("noise") or {"model": "white"}
        if noise["model"] != "white":
            line += f", disturbance std {math.sqrt(noise['disturbance_level']):.4g}"
        if self.validation is not None:
            if self.validation.get("fit_percent") is not None:
                line += (f", validation fit {self.validation['fit_percent']:.2f} % (NRMSE; "
                         f"GoF {self.validation['gof_percent']:.2f} %)")
            else:
                line += f", validation GoF {self.validation['gof_percent']:.2f} %"
        return line

    def to_json(self) -> str:
        """The report as indented JSON text, ending with a newline."""
        return json.dumps(self.to_dict(), indent=2) + "\n"

    @classmethod
    def from_dict(cls, summary: dict) -> FitReport:
        """The report of a :meth:`to_dict` (or a parsed ``summary.json``)."""
        return cls(data=summary["data"], model=summary["model"],
                   notes=tuple(summary.get("notes", ())),
                   warnings=tuple(summary.get("warnings", ())),
                   resonances=summary.get("resonances", _ABSENT),
                   order_selection=summary.get("order_selection"),
                   state_space=summary.get("state_space"),
                   validation=summary.get("validation"),
                   modes=summary.get("modes"))

    def to_markdown(self) -> str:
        """The report as a Markdown page (the content of ``summary.md``)."""
        return _markdown(self.to_dict())


def _cell_text(value) -> str:
    return f"{value:.6g}" if isinstance(value, float) else str(value)


def _noise_line(model: dict) -> str:
    """The noise line of the Markdown page, in the data's units."""
    variance, std = model["noise_level"], model.get("noise_std")
    if std is None:  # the square root of the variance
        std = math.sqrt(variance)
    shown = "beyond the float range" if variance is None else f"{variance:.6g}"
    line = f"- noise level (variance): {shown} (std {std:.6g})"
    if model.get("hyperparameter_units") == "normalized":
        line += ("; the hyperparameters below are in normalized units (u divided by "
                 "input_scale_, y_slow by output_scale_)")
    return line


def noise_summary(model, residuals=None, explanation=None) -> dict:
    """The fitted noise of a model: white, or the disturbance with its level and time scale.

    Parameters
    ----------
    model : fitted FIRGaussianProcess
    residuals : ResidualAnalysis, optional
        :func:`~gpmultirate.residuals.analyze_residuals` of the fit: the
        whiteness verdict of the slow residuals is added.
    explanation : ResidualExplanation, optional
        :func:`~gpmultirate.diagnosis.explain_residuals` of ``residuals``
        (by default made here, with the chi-squared verdict).

    Returns
    -------
    dict
        ``model`` (``"white"`` or the noise kernel), ``white_level`` (the
        white variance) and, for a disturbance, ``disturbance_level`` (its
        variance at one sample) and ``time_scale`` (its length scales and
        periods in fast samples); with ``residuals``, ``residuals_white``,
        ``ljung_box_p_value`` (chi-squared), ``whiteness_p_value`` (under the
        fitted model, where the explanation has it), and where they are not white
        ``residuals_explained`` (what is left and what takes it up,
        :func:`gpmultirate.diagnosis.explain_residuals`) and
        ``residual_remedies``; ``misspecification``, the message of the
        fit's :class:`~gpmultirate.MisspecificationWarning`, where it warned.

    Examples
    --------
    >>> import numpy as np
    >>> import gpmultirate as gm
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(90)
    >>> y = np.convolve(u, 0.8 ** np.arange(20))[:90] + 0.01 * rng.standard_normal(90)
    >>> noise_summary(gm.FIRGaussianProcess(order=20, factor=3).fit(u, y[::3]))["model"]
    'white'
    """
    kernel = getattr(model, "noise_kernel_", "white")
    found = {"model": "white" if isinstance(kernel, str) else str(kernel),
             "white_level": float(model.noise_level_)}
    if not isinstance(kernel, str):
        from gpmultirate.noise import white_level

        # the kernel's own white part (none for an AR(1) disturbance, "ar1")
        found["white_level"] = white_level(kernel)
        total = float(kernel.diag(np.zeros((1, 1)))[0])
        found["disturbance_level"] = total - found["white_level"]
        found["time_scale"] = {
            name: float(np.ravel(value)[0]) for name, value in kernel.get_params().items()
            if name.endswith(("length_scale", "periodicity")) and not name.endswith("_bounds")
        }
    if getattr(model, "misspecification_", None):
        found["misspecification"] = model.misspecification_
    if residuals is not None:
        from gpmultirate.diagnosis import explain_residuals

        why = explanation if explanation is not None else explain_residuals(residuals, model)
        found["residuals_white"] = bool(why.white)
        found["ljung_box_p_value"] = float(residuals.p_value)
        if why.calibrated:
            found["whiteness_p_value"] = float(why.p_value)
        if not why.white:
            found["residuals_explained"] = why.text
            found["residual_remedies"] = list(why.remedies)
    return found


def _noise_lines(noise) -> list[str]:
    if noise is None:
        return []
    if noise["model"] == "white":
        lines = ["- noise model: white"]
    else:
        scales = ", ".join(f"{name.rsplit('__', 1)[-1]} {value:.4g}"
                           for name, value in noise["time_scale"].items())
        white = (f"plus white noise of variance {noise['white_level']:.4g}"
                 if noise["white_level"] > 0 else "alone (no white part)")
        lines = [f"- noise model: `{noise['model']}`: a disturbance of variance "
                 f"{noise['disturbance_level']:.4g} over time ({scales} fast samples) "
                 f"{white}"]
    if "residuals_white" in noise:
        verdict = "look white" if noise["residuals_white"] else "do not look white"
        if noise.get("whiteness_p_value") is not None:
            lines.append(f"- slow residuals: {verdict} (Ljung-Box p = "
                         f"{noise['whiteness_p_value']:.3g} under the fitted model, "
                         f"{noise['ljung_box_p_value']:.3g} against chi-squared; residuals.png)")
        else:
            lines.append(f"- slow residuals: {verdict} (Ljung-Box p = "
                         f"{noise['ljung_box_p_value']:.3g}; residuals.png)")
        if noise.get("residuals_explained"):
            reasons = noise["residuals_explained"].split(": ", 1)[-1]
            lines.append(f"  - what is left: {reasons}")
    if noise.get("misspecification"):
        lines.append(f"- **the bands are not to be trusted**: {noise['misspecification']}")
    return lines


def _between_ticks_lines(between) -> list[str]:
    if not isinstance(between, dict):
        return []
    line = f"- readings between the ticks: interpolated from {between.get('lags')} lags"
    if "estimated_error_noise_std" in between:
        line += (f", estimated error {between['estimated_error_noise_std']:.2g} noise standard "
                 "deviations")
    return [line]


def _markdown(summary: dict) -> str:
    data, model = summary["data"], summary["model"]
    lines = ["# gpmultirate fit", "",
             ("- data: " if data["file"] is None else f"- data: `{data['file']}`, ")
             + f"inputs {', '.join(f'`{c}`' for c in data['inputs'])}, output `{data['output']}`",
             f"- {data['n_samples']} fast samples, {data['n_slow_samples']} measured slow "
             f"samples ({data['sampling']}), sample time {data['sample_time']:g} s",
             f"- estimator: {model['estimator']}, order {model['order']}, initial "
             f"conditions {model['initial_conditions']}",
             f"- kernel: `{model['kernel']}`",
             f"- log evidence: {model['log_evidence']:.6g}",
             _noise_line(model), *_noise_lines(model.get("noise")),
             *_between_ticks_lines(model.get("between_ticks")), "",
             "## Hyperparameters", "", "| name | value |", "|---|---|"]
    lines += [f"| `{k}` | {v} |" for k, v in model["hyperparameters"].items()]
    resonances = summary.get("resonances")
    if resonances and isinstance(resonances, list) and all(isinstance(r, dict)
                                                           for r in resonances):
        keys = list(dict.fromkeys(k for r in resonances for k in r))
        lines += ["", "## Resonances found", "", "| " + " | ".join(keys) + " |",
                  "|" + "---|" * len(keys)]
        lines += ["| " + " | ".join(_cell_text(r.get(k)) for k in keys) + " |"
                  for r in resonances]
    elif "resonances" in summary:
        lines += ["", "## Resonances found", "", "```",
                  json.dumps(summary["resonances"], indent=1), "```"]
    selection = summary.get("order_selection")
    if isinstance(selection, dict) and isinstance(selection.get("orders"), list):
        criterion = selection.get("criterion")
        lines += ["", f"## Order selection (fitted order {selection.get('best_order')})", ""]
        if criterion == "prior_tail":
            # the score is the lag beyond which the tuned prior is negligible, read up to
            # the order: equal to the order, it says the prior has not decayed there
            lines += ["| order fitted | tuned prior negligible beyond lag |", "|---|---|"]
            lines += [f"| {o} | " + (f"not within the order ({int(v)})" if int(v) >= o
                                     else f"{int(v)}") + " |"
                      for o, v in zip(selection["orders"], selection.get("score", []))]
        else:
            what = ("held-out fit in percent at the tuned values" if criterion == "held_out_fit"
                    else f"{criterion} per slow sample")
            lines += [f"| order | {what} |", "|---|---|"]
            lines += [f"| {o} | {_cell_text(v)} |"
                      for o, v in zip(selection["orders"], selection.get("score", []))]
    if "state_space" in summary:
        lines += ["", "## State-space model", "",
                  f"- order {summary['state_space']['order']}, written to `state_space.npz`"]
    lines += _modes_lines(summary.get("modes"),
                          (model.get("noise") or {}).get("residuals_white"))
    if "validation" in summary:
        val = summary["validation"]
        lines += ["", "## Validation", "", f"- `{val['file']}`, {val['n_samples']} fast samples"]
        if val.get("fit_percent") is not None:
            lines.append(f"- fit: {val['fit_percent']:.4g} % (normalized root-mean-square "
                         "error, 100 (1 - |y - y_hat| / |y - mean y|), as other toolboxes "
                         "report it)")
        lines.append(f"- goodness of fit (paper eq. 20, model.score): "
                     f"{val['gof_percent']:.4g} % (the squared errors: 100 (1 - |y - y_hat|^2 "
                     "/ |y - mean y|^2))")
    if summary["notes"]:
        lines += ["", "## Notes", ""] + [f"- {note}" for note in summary["notes"]]
    return "\n".join(lines) + "\n"


def _interval(low, high) -> str:
    return "-" if low is None or high is None else f"{low:.4g} .. {high:.4g}"


def _modes_lines(modes, noise_white=None) -> list[str]:
    if not isinstance(modes, dict):
        return []
    level = 100 * modes["level"]
    lines = ["", f"## Modes of the reduced model ({modes['n_states']} states; {level:g} % "
                 f"credible intervals from {modes['n_draws']} posterior draws)", "",
             "| frequency [Hz] | interval | damping | interval | gain | interval | in draws |",
             "|---|---|---|---|---|---|---|"]
    for m in modes["modes"]:
        lines.append(f"| {m['frequency']:.4g} | {_interval(*m['frequency_interval'])} | "
                     f"{m['damping']:.3g} | {_interval(*m['damping_interval'])} | "
                     f"{m['gain']:.4g} | {_interval(*m['gain_interval'])} | "
                     f"{100 * m['presence']:.0f} % |")
    lines += ["", "Peaks of the frequency response (posterior mean), and whether the data "
                  f"support them (the peak stands above its valleys in at least {level:g} % "
                  "of the draws):", "",
              "| frequency [Hz] | magnitude | in draws | supported | mode |",
              "|---|---|---|---|---|"]
    for p in modes["peaks"]:
        mode = "-" if p["mode"] is None else f"{modes['modes'][p['mode']]['frequency']:.4g} Hz"
        lines.append(f"| {p['frequency']:.4g} | {p['magnitude']:.4g} | "
                     f"{100 * p['probability']:.0f} % | {'yes' if p['supported'] else 'no'} | "
                     f"{mode} |")
    lines += ["", f"- {modes['text']}"]
    if noise_white is False:
        lines.append("- the slow residuals are not white: these intervals and the peaks' "
                     "support are too narrow until the model explains them")
    return lines


def _hyperparameters(kernel) -> dict:
    params = kernel.get_params(deep=True)
    return {hyper.name: _plain(params[hyper.name]) for hyper in kernel.hyperparameters
            if params.get(hyper.name) is not None}


def _noise_in_data_units(model) -> dict:
    """``noise_level`` (a variance) in the data's units, and ``noise_std`` where it is not
    the square root of that (normalized hyperparameters).

    A model whose hyperparameters stay in normalized units
    (``hyperparameter_units_ == "normalized"``: ``y_slow`` divided by
    ``output_scale_``) has them scaled here: the standard deviation is
    ``sqrt(noise_level_) * output_scale_`` (finite wherever it is
    representable), the variance its square (``inf`` or 0 where that is
    beyond the float range); the kernel's hyperparameters are reported as
    they are, with ``hyperparameter_units`` ``"normalized"``.
    """
    noise = float(model.noise_level_)
    if getattr(model, "hyperparameter_units_", "data") != "normalized":
        return {"noise_level": noise}
    exponent = int(np.frexp(model.output_scale_)[1] - 1)
    with np.errstate(over="ignore", under="ignore"):
        std = float(np.ldexp(math.sqrt(noise), exponent))
        variance = float(np.ldexp(noise, 2 * exponent))
    return {"noise_level": variance, "noise_std": std, "hyperparameter_units": "normalized"}


def fit_report(model, samples: SlowSamples | None = None, *, file=None, inputs=None,
               output: str = "y", validation=None, validation_file=None, state_space=None,
               notes=(), warnings=(), kernel_option: str | None = None,
               residuals=None, residual_explanation=None, modes=None) -> FitReport:
    """The report of a fitted :class:`~gpmultirate.FIRGaussianProcess`.

    Parameters
    ----------
    model : FIRGaussianProcess
        A fitted estimator.
    samples : SlowSamples, optional
        The slow samples it was fitted to (:func:`gpmultirate.io.read_slow_samples`);
        by default :func:`model_slow_samples`.
    file : str or path-like, optional
        The data file, for the report's text.
    inputs : sequence of str, optional
        Names of the input columns; default ``u`` (``u0, u1, ...`` for several
        inputs).
    output : str, default "y"
        Name of the output column.
    validation : tuple (u, y), optional
        Validation data with the output measured at every fast sample: the
        report gets the goodness of fit ``model.score(u, y)`` and the fit
        percentage of MATLAB's ``compare``
        (:func:`gpmultirate.metrics.fit_percent`).
    validation_file : str or path-like, optional
        The file of the validation data, for the report's text.
    state_space : object with a matrix ``A``, optional
        A state-space model written beside the fit
        (:func:`gpmultirate.export.save_state_space`); its order is reported.
    notes, warnings : sequence of str
        Remarks, and the warnings the fit raised.
    kernel_option : str, optional
        The kernel as the user chose it (``gpmultirate fit --kernel``).
    residuals : ResidualAnalysis, optional
        The residual analysis of the fit: the noise section says whether
        the slow residuals look white (:func:`noise_summary`).
    residual_explanation : ResidualExplanation, optional
        Its explanation (:func:`gpmultirate.diagnosis.explain_residuals`).
    modes : ModalAnalysis, optional
        The reduced model's modes and the supported peaks
        (:func:`gpmultirate.modes.modal_analysis`): the report's ``modes``.

    Returns
    -------
    FitReport

    Examples
    --------
    >>> import numpy as np
    >>> import gpmultirate as gm
    >>> from gpmultirate.report import fit_report
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(90)
    >>> g = 0.8 ** np.arange(20) * np.cos(0.7 * np.arange(20))
    >>> y = np.convolve(u, g)[:90] + 0.01 * rng.standard_normal(90)
    >>> model = gm.FIRGaussianProcess(order=20, factor=3).fit(u, y[::3])
    >>> report = fit_report(model, validation=(u, y))
    >>> report.data["sampling"], report.model["order"]
    ('one sample in 3, from row 0', 20)
    >>> bool(report.validation["gof_percent"] > 99)
    True
    >>> report.to_markdown().splitlines()[0]
    '# gpmultirate fit'
    """
    from gpmultirate.metrics import fit_percent

    check_is_fitted(model, "kernel_")
    if samples is None:
        samples = model_slow_samples(model)
    n_inputs = int(model.n_inputs_)
    if inputs is None:
        inputs = ["u"] if n_inputs == 1 else [f"u{k}" for k in range(n_inputs)]
    data = {"file": None if file is None else str(file), "inputs": list(inputs),
            "output": output, "n_samples": int(samples.n_samples),
            "n_slow_samples": int(samples.values.shape[0]), "sampling": samples.description,
            "factor": samples.factor, "offset": samples.offset,
            "sample_time": model.sample_time}
    summary = {"estimator": type(model).__name__, "order": int(model.coef_.shape[-1]),
               "n_inputs": n_inputs, "initial_conditions": model.initial_conditions}
    if kernel_option is not None:
        summary["kernel_option"] = kernel_option
    summary.update({"kernel": str(model.kernel_),
                    "hyperparameters": _hyperparameters(model.kernel_),
                    "tuning": model.tuning,
                    "log_evidence": float(model.log_marginal_likelihood_value_)})
    summary.update(_noise_in_data_units(model))
    summary["noise"] = noise_summary(model, residuals, residual_explanation)
    points = getattr(model.observation_, "points", None)
    if points is not None:  # readings between the ticks, interpolated on the integer lags
        summary["between_ticks"] = {"route": "interpolated", "lags": int(points)}
        if hasattr(model, "interpolation_error_"):
            summary["between_ticks"]["estimated_error_noise_std"] = float(
                model.interpolation_error_)
    if hasattr(model, "cv_log_predictive_likelihood_"):
        summary["cv_log_predictive"] = float(model.cv_log_predictive_likelihood_)
    selection = None
    if hasattr(model, "order_selection_"):
        found = model.order_selection_
        selection = {"criterion": found["criterion"],
                     "orders": [int(o) for o in found["order"]],
                     "score": [float(v) for v in found["score"]],
                     "best_order": int(found["best_order"])}
    checked = None
    if validation is not None:
        u_val, y_val = validation
        y_model = model.predict(u_val)
        checked = {"file": None if validation_file is None else str(validation_file),
                   "n_samples": int(np.shape(y_val)[0]),
                   "gof_percent": float(model.score(u_val, y_val)),
                   "fit_percent": float(fit_percent(y_val, y_model))}
    return FitReport(
        data=data, model=summary, notes=tuple(notes), warnings=tuple(warnings),
        resonances=_plain(model.resonances_) if hasattr(model, "resonances_") else _ABSENT,
        order_selection=selection,
        state_space=(None if state_space is None
                     else {"order": int(np.asarray(state_space.A).shape[0])}),
        validation=checked,
        modes=None if modes is None else _plain({**dataclasses.asdict(modes),
                                                 "consistent": modes.consistent,
                                                 "text": modes.text}))


def fit_files(model, u, samples: SlowSamples | None = None, *, file=None, inputs=None,
              output: str = "y", validation=None, validation_file=None, warnings=(),
              kernel_option: str | None = None, xscale: str = "auto") -> tuple[dict, FitReport]:
    """Every file ``gpmultirate fit`` writes for a fitted model, as bytes.

    Parameters
    ----------
    model : FIRGaussianProcess
        A fitted estimator.
    u : array-like of shape (n_samples,) or (n_samples, n_inputs)
        The input it was fitted to.
    samples, file, inputs, output, validation, validation_file, warnings, kernel_option
        As for :func:`fit_report`.
    xscale : {"auto", "linear", "log"}, default="auto"
        The frequency axis of ``bode.png``
        (:func:`gpmultirate.plotting.report.fit_figures`).

    Returns
    -------
    files : dict of str to bytes
        ``model.npz`` (:func:`gpmultirate.save_model`), ``state_space.npz``
        when the model has a state-space reduction
        (:func:`gpmultirate.export.save_state_space`; otherwise a note in
        the report says why not), the figures ``bode.png``, ``impulse.png``
        and ``intersample.png`` (:func:`gpmultirate.plotting.report.fit_figures`),
        ``residuals.png`` (:func:`gpmultirate.plotting.plot_residuals` of the
        slow residuals), ``summary.json`` and ``summary.md``.  Write them with
        :func:`gpmultirate.io.write_folder`.
    report : FitReport

    Raises
    ------
    ValueError
        If the model cannot be saved.

    Notes
    -----
    The work runs with as many BLAS threads as there are idle cores
    (:func:`gpmultirate.inference.idle_cores`), as the fit's large
    factorizations do.

    Examples
    --------
    >>> import numpy as np
    >>> import gpmultirate as gm
    >>> from gpmultirate.report import fit_files
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(60)
    >>> g = 0.8 ** np.arange(15) * np.cos(0.7 * np.arange(15))
    >>> y = np.convolve(u, g)[:60] + 0.01 * rng.standard_normal(60)
    >>> model = gm.FIRGaussianProcess(order=15, factor=3).fit(u, y[::3])
    >>> files, report = fit_files(model, u)
    >>> sorted(files)  # doctest: +NORMALIZE_WHITESPACE
    ['bode.png', 'impulse.png', 'intersample.png', 'model.npz', 'residuals.png',
     'state_space.npz', 'summary.json', 'summary.md']
    """
    from threadpoolctl import threadpool_limits

    from gpmultirate.inference import idle_cores

    # threaded BLAS on a busy machine spins against the other work: a 1023 x 1023
    # SVD of the state-space reduction took 20 s on two threads, 1.1 s on one
    with threadpool_limits(limits=idle_cores(), user_api="blas"):
        return _fit_files(model, u, samples, file=file, inputs=inputs, output=output,
                          validation=validation, validation_file=validation_file,
                          warnings=warnings, kernel_option=kernel_option, xscale=xscale)


def _fit_files(model, u, samples, *, file, inputs, output, validation, validation_file,
               warnings, kernel_option, xscale="auto"):
    import io

    from gpmultirate.export import save_state_space
    from gpmultirate.persistence import save_model
    from gpmultirate.plotting.report import fit_figures
    from gpmultirate.progress import step
    from gpmultirate.residuals import analyze_residuals

    if samples is None:
        samples = model_slow_samples(model)
    files, notes, system = {}, [], None
    buffer = io.BytesIO()
    try:
        save_model(model, buffer)
    except (ValueError, TypeError) as error:
        raise ValueError(f"the model cannot be saved: {error}") from None
    files["model.npz"] = buffer.getvalue()
    try:
        with step("state space"):
            system = model.to_state_space()
    except ValueError as error:
        notes.append(f"state_space.npz was not written: {error}")
    if system is not None:
        buffer = io.BytesIO()
        save_state_space(system, buffer, sample_time=model.sample_time)
        files["state_space.npz"] = buffer.getvalue()
    analysis = None
    try:
        # MATLAB's 25 lags, fewer for a short record
        max_lag = min(25, samples.values.shape[0] // 2)
        times = getattr(samples, "stamps", None)  # a slow log: in seconds, as the model reads them
        with step("residuals"):
            analysis = analyze_residuals(model, u, samples.values,
                                     None if times is not None else samples.indices,
                                     sample_times=times, max_lag=max(max_lag, 1))
    except ValueError as error:
        notes.append(f"residuals.png was not written: {error}")
    explanation = modes = None
    if analysis is not None:
        from gpmultirate.diagnosis import explain_residuals

        with step("residuals"):
            explanation = explain_residuals(analysis, model, u=u)
        if not explanation.white:
            notes.append(explanation.text)
    if system is not None and hasattr(model, "sample_impulse_responses"):
        from gpmultirate.modes import modal_analysis

        try:
            with step("modes"):
                modes = modal_analysis(model, system=system)
        except (ValueError, np.linalg.LinAlgError) as error:
            notes.append(f"the modes were not analysed: {error}")
        else:
            if not modes.consistent:
                notes.append(modes.text)
    with step("summary"):
        report = fit_report(model, samples, file=file, inputs=inputs, output=output,
                            validation=validation, validation_file=validation_file,
                            state_space=system, notes=notes, warnings=warnings,
                            kernel_option=kernel_option, residuals=analysis,
                            residual_explanation=explanation, modes=modes)
    figures = fit_figures(model, u, samples, inputs, xscale=xscale)
    with step("figures"):
        files.update(_drawn(figures, analysis))
    with step("summary"):
        files["summary.json"] = report.to_json().encode("utf-8")
        files["summary.md"] = report.to_markdown().encode("utf-8")
    return files, report


def _drawn(figures, analysis) -> dict:
    """The figures as PNG bytes, with that of the residuals when they were analysed."""
    import io

    from gpmultirate.plotting.report import _figure
    from gpmultirate.plotting.residuals import plot_residuals

    files = {}
    if analysis is not None:
        figure = _figure(figsize=(6.4, 2.4 * (1 + analysis.cross_correlation.shape[0])))
        plot_residuals(analysis, ax=figure.subplots(1 + analysis.cross_correlation.shape[0], 1,
                                                     squeeze=False)[:, 0])
        figures["residuals.png"] = figure
    for name, figure in figures.items():
        buffer = io.BytesIO()
        figure.savefig(buffer, format="png", dpi=150)
        files[name] = buffer.getvalue()
    return files


def readings_model(model, *, exposure=None, latency=None):
    """The model with the sensor's exposure and latency of the readings it predicts.

    A model fitted on the ticks predicts readings as the output at their
    instants; a camera's readings are the mean output over an exposure,
    shown late by a latency.  The fitted model is not changed: the result
    is a shallow copy whose ``exposure`` and ``latency`` (in the units of
    the model's ``sample_time``, fast sample periods without one, as the
    estimator's parameters) are those given, the others kept.

    Parameters
    ----------
    model : fitted FIRGaussianProcess
    exposure, latency : float, optional
        In the units of the model's ``sample_time`` (fast sample periods
        without one), non-negative; None keeps the model's.

    Returns
    -------
    estimator
        ``model`` itself when nothing changes.

    Raises
    ------
    ValueError
        If a value is negative or not finite, or the model has no readings
        (no ``exposure`` parameter).

    Examples
    --------
    >>> import numpy as np
    >>> import gpmultirate as gm
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(60)
    >>> y = np.convolve(u, 0.8 ** np.arange(10))[:60]
    >>> model = gm.FIRGaussianProcess(order=10, factor=3).fit(u, y[::3])
    >>> camera = readings_model(model, exposure=0.5)
    >>> camera.exposure, model.exposure
    (0.5, 0.0)
    """
    import copy

    given = {name: value for name, value in (("exposure", exposure), ("latency", latency))
             if value is not None}
    if not given:
        return model
    params = model.get_params(deep=False) if hasattr(model, "get_params") else {}
    for name, value in given.items():
        if name not in params:
            raise ValueError(f"{name} applies to a model of readings (FIRGaussianProcess); "
                             f"{type(model).__name__} has none")
        if isinstance(value, bool) or not isinstance(value, (int, float, np.number)) \
                or not np.isfinite(value) or value < 0:
            raise ValueError(f"{name} must be a non-negative number (in the units of the "
                             f"model's sample_time); got {value!r}")
    changed = copy.copy(model)
    for name, value in given.items():
        setattr(changed, name, float(value))
    return changed


def prediction_csv(model, u, sample_times=None, *, exposure=None, latency=None) -> str:
    """The fast-rate prediction of a fitted model as CSV text (``gpmultirate predict``).

    Parameters
    ----------
    model : fitted estimator
        ``FIRGaussianProcess``, ``LeastSquaresFIR`` or ``MultiOutputFIR``.
    u : array-like of shape (n_samples,) or (n_samples, n_inputs)
    sample_times : array-like of float, optional
        Predict the readings at these instants (in the units of the model's
        ``sample_time``, ``model.predict(u, sample_times=...)``) instead of the fast samples:
        one row per reading, ``index`` its number and ``time`` its instant.
    exposure, latency : float, optional
        With ``sample_times``: the sensor's exposure and latency in the units
        of the model's ``sample_time``, in place of the model's
        (:func:`readings_model`).

    Returns
    -------
    str
        A header ``index,time,y,y_std`` (``y_j,y_std_j`` for every output
        ``j`` of a many-output model) and one row per fast sample, the
        numbers with 17 significant digits; ``time`` is ``index`` times the
        model's ``sample_time``.

    Raises
    ------
    ValueError
        If a predicted mean or standard deviation is not finite: no table
        holds ``nan`` or ``inf``.

    Examples
    --------
    >>> import numpy as np
    >>> import gpmultirate as gm
    >>> from gpmultirate.report import prediction_csv
    >>> u = np.random.default_rng(0).standard_normal(40)
    >>> y = np.convolve(u, [1.0, 0.5])[:40]
    >>> model = gm.LeastSquaresFIR(order=2).fit(u, y)
    >>> print(prediction_csv(model, [1.0, 0.0]).splitlines()[0])
    index,time,y,y_std
    """
    if sample_times is None:
        if exposure is not None or latency is not None:
            raise ValueError("exposure and latency apply to readings: give sample_times")
        mean, std = model.predict(u, return_std=True)
    else:
        model = readings_model(model, exposure=exposure, latency=latency)
        mean, std = model.predict(u, return_std=True, sample_times=sample_times)
    if not (np.isfinite(mean).all() and np.isfinite(std).all()):
        raise ValueError("the prediction is not finite (the model or the inputs are out of "
                         "range)")
    several = mean.ndim == 2  # a many-output model predicts one column per output
    mean, std = mean.reshape(mean.shape[0], -1), std.reshape(std.shape[0], -1)
    models = getattr(model, "estimators_", [model])
    sample_time = float(getattr(models[0], "sample_time", 1.0))
    names = ([f"y_{j},y_std_{j}" for j in range(mean.shape[1])] if several else ["y,y_std"])
    rows = [",".join(["index,time", *names])]
    instants = (np.arange(mean.shape[0]) if sample_times is None
                else in_fast_periods(sample_times, sample_time))
    for k, (m, s) in enumerate(zip(mean, std)):
        values = ",".join(f"{a:.17g},{b:.17g}" for a, b in zip(m, s))
        rows.append(f"{k},{instants[k] * sample_time:.17g},{values}")
    return "\n".join(rows) + "\n"


def prediction_messages(model, out, table: str, readings: bool, sensor: dict) -> list[str]:
    r"""The lines ``gpmultirate predict`` says after writing ``table`` to ``out``.

    ``readings`` tells a table of readings at the stamps of a slow log from
    one of fast samples; ``sensor`` holds the ``exposure`` and ``latency``
    given for them (in the units of the model's ``sample_time``, seconds on
    the command line), in place of the model's.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> model = SimpleNamespace(sample_time=0.01, exposure=0.0, latency=0.0)
    >>> prediction_messages(model, "r.csv", "h\n1\n2\n", True, {"exposure": 0.005})
    ['wrote r.csv (2 readings, exposure 0.005 s, latency 0 s)']
    """
    rows = table.count("\n") - 1
    if not readings:
        return [f"wrote {out} ({rows} fast samples)"]
    exposure, latency = (sensor.get(name, getattr(model, name, 0.0) or 0.0)
                         for name in ("exposure", "latency"))
    lines = [f"wrote {out} ({rows} readings, exposure {exposure:g} s, latency {latency:g} s)"]
    if not sensor and not (exposure or latency):
        lines.append("note: the readings are the output at their stamps (the model has no "
                     "exposure or latency); give --exposure/--latency for a sensor that has "
                     "them")
    return lines


def study_header(result) -> str:
    """One paragraph describing a study: what its table's numbers are and its settings.

    Parameters
    ----------
    result : StudyResult

    Returns
    -------
    str
    """
    low, high = result.snr_range
    return (f"Goodness of fit [%] of fast-rate FIR models on noise-free validation data: "
            f"mean ± sample std over {result.n_runs} run(s); N = {result.n_samples} fast "
            f"samples, M = {result.n_slow_samples} slow samples (factor {result.factor}), SNR "
            f"{low:g}-{high:g} dB, seed {result.random_state}."
            + (" LS is not identifiable for P >= M." if "LS" in result.methods else ""))


def write_study(result, folder) -> list:
    """Write a study's tables to a folder: the tables of ``gpmultirate demo``.

    Parameters
    ----------
    result : StudyResult
    folder : str or path-like
        An existing folder.

    Returns
    -------
    list of pathlib.Path
        The files written: ``study.csv`` (the summary), ``study_runs.csv``
        (every fit), ``study.json`` (:meth:`StudyResult.from_json` reads it
        back), ``study.md`` and ``study.rst`` (the table under
        :func:`study_header`).

    Examples
    --------
    >>> import tempfile
    >>> from gpmultirate.study import run_paper_study
    >>> from gpmultirate.report import write_study
    >>> result = run_paper_study(1, [6], ["LS"], n_samples=30, factor=3, n_jobs=1)
    >>> [path.name for path in write_study(result, tempfile.mkdtemp())]
    ['study.csv', 'study_runs.csv', 'study.json', 'study.md', 'study.rst']
    """
    from pathlib import Path

    folder = Path(folder)
    header = study_header(result)
    result.to_csv(folder / "study.csv")
    result.to_csv(folder / "study_runs.csv", runs=True)
    result.to_json(folder / "study.json")
    (folder / "study.md").write_text(f"# gpmultirate demo\n\n{header}\n\n"
                                     f"{result.to_markdown()}", encoding="utf-8")
    (folder / "study.rst").write_text(f"{header}\n\n{result.to_rst()}", encoding="utf-8")
    return [folder / name for name in ("study.csv", "study_runs.csv", "study.json",
                                       "study.md", "study.rst")]
