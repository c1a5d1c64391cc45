"""Vibration suppression and defect detection in spring-mass chains.

The Python face of the Rust crate ``springmass``: numpy arrays in and out,
the numbers computed by the same Rust core as the ``springmass`` command.

Functions
---------
fit
    Fit defects (positions, kinds, values with standard errors) to a measured
    series ``x(t)`` of mass 1; the number of defects and the noise level can
    be estimated from the data.
simulate
    Time series of a chain hit by an impulse on mass 1, optionally noisy.
response
    Laplace-domain response ``X(s)`` of a chain at real or complex ``s``.
controls
    The vibration-suppression forces of Theorem 3.1 and Corollary 3.2.
laplace
    Laplace transform of a sampled series with an error estimate per ``s``.
locate
    One mass defect located by the explicit relations of section 4.1.
scene
    A reference chain of the paper (``"S3"`` is Table 1's System 3).
read_csv
    A measured series from a CSV file (the command line's reader).
fit_many
    :func:`fit` or :func:`fit_profile` of many records on a thread pool.
update_from_modes
    Structural model updating from measured modes (frequencies, shapes).
fit_ambient
    Output-only fit of ambient records (several channels).
fit_scene
    A fit scene (TOML): several sensors, several records or modal data,
    as ``springmass fit --scene``.

Errors
------
Invalid input raises ``ValueError`` whose message names the field and the
allowed range (the Rust library's message); its attributes ``field``,
``value`` and ``allowed`` repeat them. File errors raise ``OSError``; data
that cannot resolve the answer raise :class:`UnresolvableError` (a
``ValueError``), a failed numerical method :class:`NumericalError` (a
``RuntimeError``).

Examples
--------
>>> import numpy as np, springmass
>>> t = np.arange(0, 150, 0.25)
>>> x = springmass.simulate(5, defects=[("mass", 2, 3.0)], t=t, noise="rel:1e-3", seed=1)
>>> r = springmass.fit(t, x, n=5)
>>> (r.k, r.defects[0].at)
(1, 2)
"""

from __future__ import annotations

import json
import math
import numbers
import operator
import os
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from . import _core
from ._core import NumericalError, UnresolvableError, __version__

__all__ = [
    "__version__",
    "fit_profile",
    "ProfileResult",
    "ProfileValue",
    "Defect",
    "DefectEstimate",
    "ParamEstimate",
    "Alternative",
    "KRow",
    "FitResult",
    "LaplaceTransform",
    "Location",
    "Scene",
    "UnresolvableError",
    "NumericalError",
    "fit",
    "fit_many",
    "simulate",
    "response",
    "controls",
    "laplace",
    "locate",
    "scene",
    "read_csv",
    "spectral",
    "SpectralResult",
    "update_from_modes",
    "fit_scene",
    "fit_ambient",
    "searches",
]


# ---------------------------------------------------------------- input checks


def _invalid(field_name: str, value: Any, allowed: str) -> ValueError:
    """A ValueError in the library's form: ``invalid FIELD = VALUE: allowed ALLOWED``."""
    err = ValueError(f"invalid {field_name} = {value}: allowed {allowed}")
    err.kind = "InvalidParameter"  # type: ignore[attr-defined]
    err.field = field_name  # type: ignore[attr-defined]
    err.value = str(value)  # type: ignore[attr-defined]
    err.allowed = allowed  # type: ignore[attr-defined]
    return err


def _short(v: Any) -> str:
    text = repr(v)
    return text if len(text) <= 60 else text[:57] + "..."


def _records(records: Any) -> Dict[str, Any]:
    """The native keywords of ``fit(records=...)``: each record's times,
    values and measured force (or None)."""
    if isinstance(records, (str, bytes)) or not isinstance(records, Sequence):
        raise _invalid("records", _short(records), "a sequence of (t, x) or (t, x, force) tuples")
    ts, xs, fs = [], [], []
    for i, rec in enumerate(records):
        if not isinstance(rec, (tuple, list)) or len(rec) not in (2, 3):
            raise _invalid(f"records[{i}]", _short(rec), "a (t, x) or (t, x, force) tuple")
        ts.append(_vector(f"records[{i}].t", rec[0]))
        xs.append(_vector(f"records[{i}].x", rec[1]))
        f = rec[2] if len(rec) == 3 else None
        fs.append(None if f is None else _vector(f"records[{i}].force", f))
    return {"record_t": ts, "record_x": xs, "record_force": fs}


def _vector(name: str, v: Any) -> np.ndarray:
    """A one-dimensional float64 array (lists, any real dtype, any strides)."""
    try:
        a = np.asarray(v)
    except Exception as e:  # ragged lists and the like
        raise _invalid(name, _short(v), f"a one-dimensional array of real numbers ({e})") from None
    if a.dtype.kind == "c":
        raise _invalid(name, f"an array of dtype {a.dtype}", "real numbers (no complex values)")
    if a.dtype.kind in "mM":
        raise _invalid(
            name,
            f"an array of dtype {a.dtype}",
            "real numbers (convert datetimes to seconds first, e.g. (t - t[0]) / np.timedelta64(1, 's'))",
        )
    if a.dtype.kind not in "biuf":
        try:
            a = a.astype(np.float64)
        except (TypeError, ValueError):
            raise _invalid(name, _short(v), "a one-dimensional array of real numbers") from None
    if a.ndim != 1:
        raise _invalid(name, f"an array of shape {a.shape}", "a one-dimensional array")
    return np.asarray(a, dtype=np.float64)


def _real(name: str, v: Any) -> float:
    """A real number (NaN and infinities pass: the library names them)."""
    if isinstance(v, bool) or not isinstance(v, numbers.Real):
        raise _invalid(name, _short(v), "a real number")
    return float(v)


def _count(name: str, v: Any) -> int:
    """A non-negative integer (the library checks its range)."""
    if isinstance(v, bool):
        raise _invalid(name, _short(v), "a non-negative integer")
    try:
        i = operator.index(v)
    except TypeError:
        raise _invalid(name, _short(v), "a non-negative integer") from None
    if not 0 <= i < 2**64:
        raise _invalid(name, i, "a non-negative integer below 2**64")
    return i


# The largest chain (springmass::chain::MAX_N).
_MAX_N = 1_000_000_000


def _chain_size(v: Any) -> int:
    """A number of masses: one message for every out-of-range value (0, -3, 2**70)."""
    allowed = f"1 <= n <= {_MAX_N}"
    if isinstance(v, bool):
        raise _invalid("n", _short(v), allowed)
    try:
        i = operator.index(v)
    except TypeError:
        raise _invalid("n", _short(v), allowed) from None
    if not 1 <= i <= _MAX_N:
        raise _invalid("n", i, allowed)
    return i


def _text(name: str, v: Any) -> str:
    if not isinstance(v, str):
        raise _invalid(name, _short(v), "a string")
    return v


def _trigger(v: Any) -> str:
    """``"auto"`` or a time, as the core's text form."""
    if isinstance(v, str):
        return v
    if isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool):
        return repr(float(v))
    raise _invalid("trigger", _short(v), '"auto" or a time (a finite number)')


# ---------------------------------------------------------------- defects


@dataclass(frozen=True)
class Defect:
    """One place where the chain differs from the uniform chain.

    Parameters
    ----------
    kind : {"mass", "spring", "damper", "ground"}
        What differs (``"ground"``: a spring from a mass to the ground).
    at : int
        Position: masses, dampers and ground springs ``1..=n``, springs
        ``0..=n`` (spring ``i`` joins masses ``i`` and ``i + 1``; ``0`` and
        ``n`` are the wall springs).
    value : float
        The defect's mass, stiffness or damping.

    Examples
    --------
    >>> Defect("mass", 8, 5.0)
    Defect(kind='mass', at=8, value=5.0)
    >>> str(Defect("spring", 3, 0.5))
    'spring:3:0.5'
    """

    kind: str
    at: int
    value: float

    def __str__(self) -> str:
        return f"{self.kind}:{self.at}:{self.value!r}"


DefectLike = Union[Defect, Tuple[str, int, float], str]


def _defect_text(name: str, d: Any) -> str:
    """``kind:at:value`` for the library's parser (which names what is wrong)."""
    if isinstance(d, Defect):
        return str(d)
    if isinstance(d, str):
        return d
    if isinstance(d, (tuple, list)) and len(d) == 3:
        kind, at, value = d
        if isinstance(value, numbers.Real) and not isinstance(value, bool):
            value = repr(float(value))
        return f"{kind}:{at}:{value}"
    raise _invalid(
        name, _short(d), 'a Defect, a tuple (kind, at, value) such as ("mass", 8, 5.0), or "mass:8:5"'
    )


def _defects(name: str, ds: Any) -> List[str]:
    if isinstance(ds, (Defect, str)) or (isinstance(ds, tuple) and len(ds) == 3 and isinstance(ds[0], str)):
        ds = [ds]
    try:
        items = list(ds)
    except TypeError:
        raise _invalid(name, _short(ds), "a sequence of defects") from None
    return [_defect_text(f"{name}[{i}]", d) for i, d in enumerate(items)]


def _defect_from_json(d: Dict[str, Any]) -> Defect:
    # the one field besides kind and at is the value (m, k, d or g)
    value = next(v for key, v in d.items() if key not in ("kind", "at"))
    return Defect(d["kind"], int(d["at"]), float(value))


def _chain(
    n: Any, k: Any, d: Any, gamma: Any, mass: Any, defects: Any, left: Any, right: Any, damping: Any = None
) -> Dict[str, Any]:
    return {
        "n": _chain_size(n),
        "k": _real("k", k),
        # None: 0.1 (grounded), 0 with another damping model
        "d": None if d is None else _real("d", d),
        "damping": None if damping is None else _text("damping", damping),
        "gamma": _real("gamma", gamma),
        "mass": _real("mass", mass),
        "defects": _defects("defects", defects),
        "left": _text("left", left),
        "right": _text("right", right),
    }


def _fit_text(fit: Union[str, Sequence[str]]) -> str:
    """Chain parameters to fit, as the comma-separated text the core reads."""
    if isinstance(fit, str):
        return fit
    return ",".join(_text(f"fit[{i}]", p) for i, p in enumerate(fit))


def _noise_text(noise: Union[str, float]) -> str:
    """``"auto"`` or a standard deviation, as the text the core reads."""
    return noise if isinstance(noise, str) else repr(_real("noise", noise))


def _nan(v: Optional[float]) -> float:
    """JSON null (the library's NaN) back to NaN."""
    return math.nan if v is None else float(v)


# ---------------------------------------------------------------- fit


@dataclass(frozen=True)
class DefectEstimate:
    """One defect found by :func:`fit`.

    Attributes
    ----------
    kind : str
        ``"mass"``, ``"spring"`` or ``"damper"``.
    at : int
        Position.
    value : float
        Fitted value.
    se : float
        Its standard error (NaN when the data do not constrain it, 0 for a
        known defect).
    at_bound : bool
        The value ended on a bound of its range.
    known : bool
        Given by ``known=``, not fitted.
    significance : float
        Standard errors from "no defect", ``|value - uniform| / se`` (on a
        baseline ``|value - baseline| / se``).
    identifiable : bool
        Whether the data single out its position and value.
    baseline : float or None
        The baseline's value at this site (``fit(baseline=...)``); None on
        the uniform chain.
    interval : (float, float) or None
        The interval at the fit's ``level`` (default 0.9): Wald where the
        profile likelihood agrees, else the profile-likelihood interval.
    interval_method : str or None
        ``"wald"``, ``"profile"``, ``"profile-bounded"``, ``"unconstrained"``
        or ``"known"``.
    """

    kind: str
    at: int
    value: float
    se: float
    at_bound: bool
    known: bool
    significance: float
    identifiable: bool
    baseline: Optional[float] = None
    interval: Optional[Tuple[float, float]] = None
    interval_method: Optional[str] = None

    @property
    def defect(self) -> Defect:
        """As a :class:`Defect`."""
        return Defect(self.kind, self.at, self.value)


@dataclass(frozen=True)
class ParamEstimate:
    """A fitted chain parameter (``d``, ``gamma``, ``k`` or ``mass``) with its standard error."""

    name: str
    value: float
    se: float
    at_bound: bool
    interval: Optional[Tuple[float, float]] = None
    interval_method: Optional[str] = None


@dataclass(frozen=True)
class Alternative:
    """A runner-up answer: its defects, chi-square and gap to the best (above 9: 3 sigma worse)."""

    defects: Tuple[Defect, ...]
    chi2: float
    gap: float


@dataclass(frozen=True)
class KRow:
    """The evidence for one number of defects ``k`` (``criterion``: smaller is better)."""

    k: int
    chi2: float
    params: int
    criterion: float
    positions: Tuple[int, ...]


@dataclass(frozen=True, eq=False)
class FitResult:
    """The answer of :func:`fit`, with error bars first.

    Attributes
    ----------
    defects : list of DefectEstimate
        The defects found (known ones included and flagged).
    k : int
        Number of defects fitted (known ones excluded).
    params : list of ParamEstimate
        Chain parameters fitted (``fit=``).
    sigma : float
        Noise standard deviation of the samples used for the final fit.
    sigma_estimated : bool
        Whether ``sigma`` was estimated from the data (``noise="auto"``).
    chi2, dof : float, int
        Final chi-square and its degrees of freedom.
    status : str
        ``"converged"``, ``"budget-exhausted"``, ``"stalled"``,
        ``"model-mismatch"`` (the residual is not noise: the model does not
        explain the record), ``"value-at-bound"`` or ``"not-identifiable"``.
    message : str
        One line on the status.
    resolved : bool
        The runner-up is clearly worse and every defect is identifiable.
    fits_data : bool
        The residual is consistent with noise (``fit_p_value >= 0.001``).
    fit_p_value : float
        p-value behind ``fits_data``.
    alternatives : list of Alternative
        The next best answers, best first.
    k_selection : list of KRow
        The evidence for each number of defects tried.
    criterion, misfit, method : str
        How ``k`` was chosen, the misfit and the search used.
    evaluations, sets_fitted : int
        Misfit evaluations spent; position sets fitted for the chosen ``k``.
    hypotheses : list of dict
        The most probable hypotheses (at most 10), best first: ``defects``
        (dicts with ``kind``, ``at`` and the value), ``k``, ``chi2``,
        ``log_evidence`` and ``probability`` (Laplace evidence under the
        stated prior, normalised over the hypotheses refitted).
    k_probability : dict of int to float
        The probability of each number of defects searched.
    position_probability : list of dict
        ``kind``, ``at``, ``probability``: the marginal probability of a
        defect at each site any refitted hypothesis holds.
    answer_probability : float
        The probability of the reported answer.
    pruned_bound : float
        The largest share of probability the hypotheses not refitted could
        hold.
    level : float
        The level of the intervals.
    wall_time_s : float
        Wall time of the fit in seconds.
    identifiability : dict or None
        The library's identifiability report of the best answer.
    visibility : dict or None
        How deep the data see a 10% mass change (``depth`` in masses from
        the observed one, ``se`` of a change at each mass, ``hidden``: fitted
        defects beyond that depth); mass defects only.
    unseen : dict or None
        With the number of defects left to the criterion, the masses and
        springs the answer leaves unchanged whose halving or doubling the
        data would not show: ``elements`` (each ``kind``, ``at``),
        ``checked`` and ``of`` (elements probed, of those left unchanged).
        Non-empty ``elements`` make the status ``not-identifiable``: a
        further defect could hide there. ``None`` when not checked.
    noise_model : dict or None
        The record's noise model: ``kind`` (``"white"`` or ``"ar"``), ``p``,
        ``coefficients``, ``innovation_sigma``, ``iterations`` (refits under
        it), ``converged``.
    whiteness_p : float or None
        Ljung-Box p-value of the residual whitened by the noise model.
    nuisance : list of dict
        The sensor's fitted ``offset`` (and ``drift``): ``name``, ``value``,
        ``se``; empty when none were fitted.
    trigger : dict or None
        The blow's time on the record's axis when the record was re-timed to
        it: ``time``, ``se``, ``dropped`` (samples before it), ``detected``,
        ``refits``; ``None`` for a record that starts with its blow.
    sensors : list of dict
        With several sensors (or several records, ``records``), each one's
        ``at``, ``kind``, ``samples``, noise level ``sigma`` (estimated from
        its own residual, or given), ``whiteness_p`` (Ljung-Box of its own
        residual) and ``fits_data`` (the joint answer explains it); ``record``
        is the record's place (1-based) with several records, else 0; empty
        for one sensor (``sigma`` is then its level).
    damping : dict or None
        The damping model and its parameters with standard errors, e.g.
        ``{"model": "rayleigh", "a": ..., "b": ..., "se": {"a": ..., "b": ...},
        "fitted": True, "candidates": [...]}`` (``None`` for the default
        grounded model not fitted); each candidate ``{"model", "criterion",
        "k", "positions", "searched"}``, ``searched`` False for a model
        fitted only at the chosen model's set. With a model given
        (``damping="between"``, ``fit=("d",)``) whose fit needed coloured
        noise, ``"checked": True`` and the candidates are the other models
        fitted with white noise; one that explains the record makes the
        status ``model-mismatch``, its message naming it.
    t, observed, predicted, residual : ndarray
        The data and the best fit's model on the same times.
    summary : str
        The library's human summary (also ``str(result)``).
    """

    defects: List[DefectEstimate]
    k: int
    params: List[ParamEstimate]
    sigma: float
    sigma_estimated: bool
    chi2: float
    dof: int
    status: str
    message: str
    resolved: bool
    fits_data: bool
    fit_p_value: float
    alternatives: List[Alternative]
    k_selection: List[KRow]
    criterion: str
    misfit: str
    method: str
    evaluations: int
    sets_fitted: int
    wall_time_s: float
    identifiability: Optional[Dict[str, Any]]
    visibility: Optional[Dict[str, Any]]
    unseen: Optional[Dict[str, Any]]
    noise_model: Optional[Dict[str, Any]]
    whiteness_p: Optional[float]
    nuisance: List[Dict[str, Any]]
    damping: Optional[Dict[str, Any]]
    trigger: Optional[Dict[str, Any]]
    sensors: List[Dict[str, Any]]
    hypotheses: List[Dict[str, Any]]
    k_probability: Dict[int, float]
    position_probability: List[Dict[str, Any]]
    answer_probability: float
    pruned_bound: float
    level: float
    t: np.ndarray
    observed: np.ndarray
    predicted: np.ndarray
    residual: np.ndarray
    summary: str
    _report: Dict[str, Any] = field(repr=False)

    def __str__(self) -> str:
        return self.summary

    def to_dict(self) -> Dict[str, Any]:
        """The report as plain Python objects, keyed as ``springmass fit --json``.

        Every key and value of the command line's JSON (NaN written as
        ``None``, as JSON has no NaN), plus ``"predicted"``: a dict of the
        lists ``t``, ``observed``, ``model`` and ``residual``.

        Returns
        -------
        dict
            Ready for :func:`json.dumps`.
        """
        out = json.loads(json.dumps(self._report))
        out["predicted"] = {
            "t": self.t.tolist(),
            "observed": self.observed.tolist(),
            "model": self.predicted.tolist(),
            "residual": self.residual.tolist(),
        }
        return out

    @classmethod
    def _from_core(cls, raw: Dict[str, Any]) -> "FitResult":
        r = json.loads(raw["report"])
        empty = np.zeros(0)
        return cls(
            defects=[
                DefectEstimate(
                    kind=d["kind"],
                    at=int(d["at"]),
                    value=_nan(d["value"]),
                    se=_nan(d["se"]),
                    at_bound=bool(d["at_bound"]),
                    known=bool(d["known"]),
                    significance=_nan(d["significance"]),
                    identifiable=bool(d["identifiable"]),
                    baseline=None if d.get("baseline") is None else _nan(d["baseline"]),
                    interval=_interval(d),
                    interval_method=d.get("interval_method"),
                )
                for d in r["defects"]
            ],
            k=int(r["k"]),
            params=[
                ParamEstimate(
                    p["name"],
                    _nan(p["value"]),
                    _nan(p["se"]),
                    bool(p["at_bound"]),
                    _interval(p),
                    p.get("interval_method"),
                )
                for p in r["params"]
            ],
            sigma=_nan(r["noise_sigma"]),
            sigma_estimated=bool(r["noise_estimated"]),
            chi2=_nan(r["chi2"]),
            dof=int(r["dof"]),
            status=r["status"],
            message=r["message"],
            resolved=bool(r["resolved"]),
            fits_data=bool(r["fits_data"]),
            fit_p_value=_nan(r["fit_p_value"]),
            alternatives=[
                Alternative(tuple(_defect_from_json(d) for d in a["defects"]), _nan(a["chi2"]), _nan(a["gap"]))
                for a in r["alternatives"]
            ],
            k_selection=[
                KRow(int(row["k"]), _nan(row["chi2"]), int(row["params"]), _nan(row["criterion"]), tuple(row["positions"]))
                for row in r["k_selection"]
            ],
            criterion=r["criterion"],
            misfit=r["misfit"],
            method=r["method"],
            evaluations=int(r["evaluations"]),
            sets_fitted=int(r["sets_fitted"]),
            wall_time_s=float(r["wall_time_s"]),
            identifiability=r.get("identifiability"),
            visibility=r.get("visibility"),
            unseen=r.get("unseen"),
            noise_model=r.get("noise_model"),
            whiteness_p=None if r.get("whiteness_p") is None else _nan(r["whiteness_p"]),
            nuisance=list(r.get("nuisance", [])),
            damping=r.get("damping"),
            trigger=r.get("trigger"),
            sensors=list(r.get("sensors", [])),
            hypotheses=list(r.get("hypotheses", [])),
            k_probability={int(e["k"]): _nan(e["probability"]) for e in r.get("k_probability", [])},
            position_probability=list(r.get("position_probability", [])),
            answer_probability=_nan(r.get("answer_probability")),
            pruned_bound=_nan(r.get("pruned_bound")),
            level=_nan(r.get("level")),
            t=raw.get("t", empty),
            observed=raw.get("observed", empty),
            predicted=raw.get("model", empty),
            residual=raw.get("residual", empty),
            summary=raw["summary"],
            _report=r,
        )


def fit(
    t: Any,
    x: Any,
    *,
    n: int,
    d: Optional[float] = None,
    fit: Union[str, Sequence[str]] = (),
    defects: Union[str, int] = "auto",
    kinds: Union[None, str, Sequence[str]] = None,
    noise: Union[str, float] = "auto",
    misfit: Optional[str] = None,
    method: Optional[str] = None,
    seed: int = 0,
    gamma: float = 1.0,
    known: Sequence[DefectLike] = (),
    criterion: str = "bic",
    max_evals: int = 20000,
    k: float = 1.0,
    mass: float = 1.0,
    left: str = "fixed",
    right: str = "fixed",
    observe: Union[int, Sequence[int]] = 1,
    observe_kind: Union[str, Sequence[str]] = "displacement",
    force: Any = None,
    noise_model: str = "auto",
    nuisance: str = "auto",
    damping: Optional[str] = None,
    trigger: Any = "auto",
    force_window: str = "auto",
    baseline: Any = None,
    level: Optional[float] = None,
    prior_k: Optional[str] = None,
    prior_range: Optional[str] = None,
    uncertainty: bool = True,
    exhaustive: bool = False,
    effort: str = "normal",
    records: Sequence[Any] = (),
) -> FitResult:
    """Fit defects to a measured series of mass 1's displacement.

    The chain is the paper's: ``n`` masses between two walls, uniform
    springs ``k = 1`` and masses 1 (scale your data to these units), damping
    ``d`` on every mass, an impulse ``gamma`` on mass 1 at ``t = 0``. The
    fit finds the defects' positions, kinds and values with standard errors;
    the number of defects and the noise level come from the data unless
    given. The same options give the same numbers as
    ``springmass fit --data FILE.csv --n N ... --json``. The GIL is
    released while the fit runs.

    Parameters
    ----------
    t : array_like, shape (N,)
        Sample times, ``>= 0``, strictly increasing (at least 16 samples).
    x : array_like, shape (N,) or (N, S)
        Displacement of mass 1 at ``t`` (finite); with several sensors one
        column per observed mass of ``observe`` (samples x sensors), fitted
        jointly, each sensor's noise level estimated (``FitResult.sensors``).
    n : int
        Number of masses.
    d : float, default 0.1
        Damping per mass (known, or the starting value with ``fit=("d",)``);
        with ``damping="between"``, ``"rayleigh"`` or ``"modal"`` an extra
        grounded damping (default 0).
    fit : str or sequence of str, default ()
        Chain parameters fitted too: any of ``"d"``, ``"gamma"``, ``"k"``,
        ``"mass"`` (at most three), or a comma-separated string.
    defects : "auto", "auto:KMAX" or int, default "auto"
        Number of defects; ``"auto"`` tries 0 to 4 (or ``n``) and chooses by
        ``criterion``.
    kinds : str or sequence of str, optional
        ``"mass"``, ``"spring"``, ``"damper"``, ``"ground"`` or ``"any"``
        (mass, spring or damper); a sequence gives
        one kind per defect (with ``defects`` the same number). Default
        ``"any"``, or ``"mass"`` with a ``method`` that places masses only
        (``"ga"``, ``"nelder-mead"``, ``"pso"``, ``"relax"``). Where the
        defects are known to be masses, ``kinds="mass"`` is about twice as
        fast and recovers them somewhat more often at high noise.
    noise : "auto" or float, default "auto"
        Standard deviation of the samples' noise, or ``"auto"`` to estimate it.
    misfit : {"time", "bromwich", "real-axis"}, optional
        The data misfit (default ``"time"``, the time-domain chi-square).
    method : str, optional
        The search over positions, a name of :func:`searches` (default
        ``"enumerate"``, or ``"greedy"`` when enumeration would pass 200 000
        position sets, and for three defects or more told in a chain of 40
        masses or more):
@SEARCHES@
    seed : int, default 0
        Seed of the stochastic searches (same seed, same answer).
    gamma : float, default 1.0
        Impulse on mass 1.
    known : sequence of Defect, (kind, at, value) or "kind:at:value", default ()
        Defects known beforehand (not fitted).
    criterion : {"bic", "aic", "chi2", "chi2:ALPHA"}, default "bic"
        How ``defects="auto"`` chooses the number.
    max_evals : int, default 20000
        Evaluation budget of the stochastic searches (@STOCHASTIC@).
    k, mass : float, default 1.0
        Uniform stiffness and mass, in the data's units (N/m and kg for SI
        data; the report's natural frequencies are then in rad/s).
    left, right : {"fixed", "free"}, default "fixed"
        The chain's ends (a shear frame seen from its roof: ``left="free"``).
    observe : int or sequence of int, default 1
        The observed mass; a sequence (one per column of a 2-D ``x``) for
        several sensors, each mass once.
    observe_kind : {"displacement", "velocity", "acceleration"} or sequence
        What ``x`` measured: one kind for every sensor or one per sensor.
    force : array_like, shape (N,), optional
        A measured force on mass 1 at the times ``t`` (a hammer test; ``t``
        then uniform from 0), used instead of the ideal impulse.
    records : sequence of tuples, optional
        Further records of the same chain (several hammer hits), each
        ``(t, x)`` or ``(t, x, force)`` with its own times and, if measured,
        its own force (else the impulse ``gamma``), of the same sensor as
        ``x``: one joint fit, a noise level per record, and
        ``FitResult.sensors`` lists every record (``record``, ``sigma``,
        ``whiteness_p``, ``fits_data``). A record the joint answer does not
        explain (its own residual is not noise) makes the status
        ``"model-mismatch"`` and is named in the message. Not with several
        sensors (a 2-D ``x``).
    noise_model : {"auto", "white", "ar", "ar:P"}, default "auto"
        The record's noise model: ``"auto"`` keeps white noise unless the
        white fit's residual fails the Ljung-Box test and an AR(p) model
        (p <= 8) wins by BIC; ``"ar"`` chooses p by BIC, ``"ar:P"`` fixes it.
        Standard errors are those of the fitted noise model.
    nuisance : {"auto", "none", "offset", "offset+drift"}, default "auto"
        A constant offset (and a linear drift) of the sensor, profiled out of
        the fit; ``"auto"`` fits them when the white fit's residual is not
        white and BIC wants them (reported with standard errors).
    damping : str, optional
        The damping model ``"MODEL[:P1[:P2]]"``: ``"grounded"`` (``d`` on
        every mass), ``"between:C"`` (a damper ``C`` parallel to every
        spring), ``"rayleigh:A:B"`` (``C = A M + B K``), ``"modal:ZETA"``
        (every mode damped with the ratio ``ZETA``) or ``"modal:Z1,Z2,Z3"``
        (a ratio per mode, the last for every higher mode; with
        ``fit=("d",)`` the starting values of the fitted ratios, reported as
        ``zeta_1``, ``zeta_2``, ..); parameters not given are fitted with
        ``fit=("d",)``. Default: grounded, or with ``fit=("d",)`` the
        model the BIC chooses (``FitResult.damping``): the models searched
        one at a time, the cheapest first and next one that does better
        at the best defects so far, until one explains the record and no
        other does better at its defects (``effort="high"`` searches every
        model).
    trigger : "auto" or float, default "auto"
        When the blow came on the record's time axis: ``"auto"`` detects a
        quiet pre-trigger segment or a clock that does not start at the blow
        (``t`` may start below 0) and fits the time with its standard error
        (``FitResult.trigger``); a number gives it.
    force_window : str, default "auto"
        With ``force``: ``"auto"`` keeps the detected pulse and sets the
        sensor's noise elsewhere to zero (a modal test's force window),
        ``"none"`` keeps every sample, ``"T0:T1"`` the samples in that range.
    baseline : str, path or dict, optional
        A measured profile instead of the uniform chain: the path of a CSV
        table (rows ``mass,spring``, see ``springmass fit --baseline``) or
        ``{"mass": [...], "spring": [...], "damper": [...]}`` (``spring``
        has ``n + 1`` values, 0 for a free end's wall spring). Its rows give
        ``n`` (which must agree) and the ends (``left``/``right`` left at
        their defaults follow the table); defects are reported relative to
        it (``DefectEstimate.baseline``).
    level : float, optional
        Level of every fitted value's interval (default 0.9):
        ``DefectEstimate.interval``, ``ParamEstimate.interval``.
    prior_k : {"uniform", "site:P"}, optional
        Prior over the number of defects for ``FitResult.hypotheses`` (their
        probabilities): every count searched equally probable (default), or
        every site defective with probability ``P``.
    prior_range : "LO:HI", optional
        Prior range of a defect's value, in multiples of the value it
        replaces (default: the search range of its kind).
    uncertainty : bool, default True
        Compute the intervals and the probabilities (False: faster, without).
    exhaustive : bool, default False
        With ``defects="auto"``, search every position (and kind) set at
        every number of defects. By default the search at three defects and
        more is nested in the best answers at one defect fewer, and
        ``kinds="any"`` tries at each position the kinds the data point to
        (much faster; the report's ``to_dict()["exhaustive"]`` is then False).
        A chain whose sets pass 200 000 (from n = 48 with up to four
        defects), searched greedily by default, is then enumerated, or
        refused at once with the count of its sets (ask for fewer defects,
        ``defects="auto:3"``).
    effort : {"low", "normal", "high"}, default "normal"
        Speed against accuracy of the search: ``"low"`` refits fewer sets
        in the time domain and, with ``defects="auto"``, nests the searches
        from three defects in 4 answers at one fewer (not 8) and stops
        raising the number of defects as soon as one more does not help; ``"high"`` refits every shortlisted set and,
        with ``defects="auto"``, searches every set at every number of
        defects up to the largest (where there are at most 200 000) and,
        with ``fit=("d",)`` and no ``damping``, searches every damping model
        (not only until one explains the record). The report's ``method``
        names a level other than normal.

    Returns
    -------
    FitResult
        Defects with standard errors, ``k``, ``sigma``, ``chi2``, ``status``,
        alternatives, the k-selection table and the predicted series.

    Raises
    ------
    ValueError
        Invalid input (NaN in ``x``, ``t`` not increasing, ``n = 0``, an
        unknown kind, ...); the message names the field and its allowed range.
    NumericalError
        Every hypothesis failed numerically.

    Examples
    --------
    >>> import numpy as np, springmass
    >>> t = np.arange(0, 150, 0.25)
    >>> x = springmass.simulate(5, defects=[("mass", 2, 3.0), ("mass", 4, 0.5)], t=t, noise="rel:1e-3", seed=3)
    >>> r = springmass.fit(t, x, n=5, defects="auto:3")
    >>> [(e.at, round(e.value, 1)) for e in r.defects]
    [(2, 3.0), (4, 0.5)]
    """
    tv = _vector("t", t)
    xv, more, sensors, sensor_kinds = _sensors(x, observe, observe_kind)
    fit_text = _fit_text(fit)
    if isinstance(defects, str):
        defects_text = defects
    else:
        defects_text = str(_count("defects", defects))
    if kinds is None or isinstance(kinds, str):
        kinds_text, slot_kinds = kinds, []
    else:
        kinds_text, slot_kinds = None, [_text(f"kinds[{i}]", k) for i, k in enumerate(kinds)]
    noise_text = _noise_text(noise)
    table = _baseline(baseline)
    if table is not None and left == "fixed" and right == "fixed":
        left_text: Optional[str] = None
        right_text: Optional[str] = None
    else:
        left_text, right_text = _text("left", left), _text("right", right)
    raw = _core.fit(
        tv,
        xv,
        n=_chain_size(n),
        d=None if d is None else _real("d", d),
        gamma=_real("gamma", gamma),
        fit=fit_text or None,
        known=_defects("known", known),
        defects=defects_text,
        kinds=kinds_text,
        slot_kinds=slot_kinds,
        noise=noise_text,
        misfit=None if misfit is None else _text("misfit", misfit),
        method=None if method is None else _text("method", method),
        criterion=_text("criterion", criterion),
        seed=_count("seed", seed),
        max_evals=_count("max_evals", max_evals),
        k=_real("k", k),
        mass=_real("mass", mass),
        left=left_text,
        right=right_text,
        observe=None if sensors else _count("observe", observe),
        observe_kind=None if sensor_kinds else _text("observe_kind", observe_kind),
        sensors=sensors,
        sensor_kinds=sensor_kinds,
        more=more,
        **_records(records),
        force=None if force is None else _vector("force", force),
        noise_model=_text("noise_model", noise_model),
        nuisance=_text("nuisance", nuisance),
        damping=None if damping is None else _text("damping", damping),
        trigger=_trigger(trigger),
        force_window=_text("force_window", force_window),
        baseline=table,
        level=None if level is None else _real("level", level),
        prior_k=None if prior_k is None else _text("prior_k", prior_k),
        prior_range=None if prior_range is None else _text("prior_range", prior_range),
        uncertainty=bool(uncertainty),
        exhaustive=bool(exhaustive),
        effort=str(effort),
    )
    return FitResult._from_core(raw)


def _sensors(x: Any, observe: Any, observe_kind: Any) -> Tuple[Any, List[Any], List[int], List[str]]:
    """``x`` (1-D, or 2-D samples x sensors) as the native fit takes it: the
    first sensor's record, the others' records, the observed masses and
    their kinds (both empty for one sensor given as a 1-D ``x`` and an int)."""
    several = not isinstance(observe, (int, np.integer))
    kinds: List[str] = []
    if not isinstance(observe_kind, str):
        kinds = [_text(f"observe_kind[{i}]", k) for i, k in enumerate(observe_kind)]
    try:
        arr = np.asarray(x)
    except Exception as e:  # ragged lists and the like
        raise _invalid("x", _short(x), f"an array of real numbers ({e})") from None
    if not several and (arr.ndim != 1 or not kinds):
        # one sensor: x one-dimensional (a 2-D x needs a list of masses)
        return _vector("x", x), [], [], []
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2:
        raise _invalid("x", f"{arr.ndim} dimensions", "1 (one sensor) or 2 (samples x sensors)")
    masses = [_count(f"observe[{i}]", m) for i, m in enumerate([observe] if not several else observe)]
    if len(masses) != arr.shape[1]:
        raise _invalid("observe", str(masses), f"one mass per column of x ({arr.shape[1]} columns)")
    if len(kinds) == 0:
        kinds = [_text("observe_kind", observe_kind)]
    columns = [_vector(f"x[:, {j}]", arr[:, j]) for j in range(arr.shape[1])]
    return columns[0], columns[1:], masses, kinds


def _interval(entry: Dict[str, Any]) -> Optional[Tuple[float, float]]:
    iv = entry.get("interval")
    return None if iv is None else (_nan(iv[0]), _nan(iv[1]))


def _baseline(value: Any) -> Any:
    """A baseline as the native fit takes it: a path, or a dict of lists."""
    if value is None:
        return None
    if isinstance(value, (str, os.PathLike)):
        return os.fspath(value)
    if isinstance(value, dict):
        unknown = set(value) - {"mass", "spring", "damper"}
        if unknown or "mass" not in value or "spring" not in value:
            raise ValueError(
                f"invalid baseline = {sorted(value)}: allowed a dict with keys mass, spring and optionally damper"
            )
        out = {key: [float(v) for v in _vector(f"baseline.{key}", value[key])] for key in ("mass", "spring")}
        if value.get("damper") is not None:
            out["damper"] = [float(v) for v in _vector("baseline.damper", value["damper"])]
        return out
    raise TypeError(f"baseline must be a path or a dict of lists, not {type(value).__name__}")


# ---------------------------------------------------------------- forward side


def searches() -> List[Dict[str, Any]]:
    """The searches over defect positions, from the library's registry.

    Parameters
    ----------
    None

    Returns
    -------
    list of dict
        One dict per search, in the order of ``springmass fit --help``:
        ``name`` (what ``fit(method=...)`` and a scene's ``search.method``
        take), ``aliases``, ``help`` (one line), ``kinds`` (``"every"``,
        ``"mass-or-spring"`` or ``"mass-only"``), ``general_scene`` (accepted
        by a scene's general fit), ``stochastic`` (seeded, with an
        evaluation budget) and ``optimizer`` (its module, or None).

    Examples
    --------
    >>> import springmass
    >>> [s["name"] for s in springmass.searches()]
    ['enumerate', 'greedy', 'relax', 'ga', 'nelder-mead', 'pso']
    >>> [s["name"] for s in springmass.searches() if s["stochastic"]]
    ['ga', 'nelder-mead', 'pso']
    """
    return [dict(s) for s in _core.searches()]


def _search_docs() -> None:
    """Fill :func:`fit`'s docstring with the registry's names and help."""
    table = searches()
    lines = "\n".join(f'        ``"{s["name"]}"``: {s["help"]}.' for s in table)
    stochastic = ", ".join(f"``{s['name']}``" for s in table if s["stochastic"])
    if fit.__doc__:
        fit.__doc__ = fit.__doc__.replace("@SEARCHES@", lines).replace("@STOCHASTIC@", stochastic)


_search_docs()


def simulate(
    n: int,
    *,
    t: Any,
    defects: Sequence[DefectLike] = (),
    d: Optional[float] = None,
    k: float = 1.0,
    gamma: float = 1.0,
    mass: float = 1.0,
    observe: Union[int, Sequence[int]] = 1,
    observe_kind: str = "displacement",
    noise: Union[None, str, float] = None,
    seed: int = 0,
    method: str = "auto",
    left: str = "fixed",
    right: str = "fixed",
    damping: Optional[str] = None,
) -> np.ndarray:
    """Simulate a chain hit by the impulse ``gamma delta(t)`` on mass 1.

    Same numbers as ``springmass simulate`` (also the noise, for the same
    seed). The GIL is released while it runs.

    Parameters
    ----------
    n : int
        Number of masses.
    t : array_like, shape (N,)
        Output times ``0, dt, 2 dt, ...`` (uniform, from 0; for example
        ``np.arange(0, 200, 0.2)``).
    defects : sequence of Defect, (kind, at, value) or "kind:at:value", default ()
        The chain's defects, e.g. ``[("mass", 8, 5.0), ("spring", 3, 0.5)]``.
    d, k, gamma, mass : float
        Uniform damping (0.1; 0 with another ``damping`` model: then an
        extra grounded damping), stiffness (1), impulse (1) and mass (1).
    damping : str, optional
        The damping model ``"grounded"`` (default), ``"between:C"`` (a
        damper ``C`` parallel to every spring), ``"rayleigh:A:B"``
        (``C = A M + B K``), ``"modal:ZETA"`` (every mode damped with the
        ratio ``ZETA``) or ``"modal:Z1,Z2,.."`` (a ratio per mode in the
        order of frequency, the last for every higher mode).
    observe : int or sequence of int, default 1
        Observed mass(es), 1-based.
    observe_kind : {"displacement", "velocity", "acceleration"}
        What is recorded.
    noise : None, float or str, default None
        Additive white Gaussian noise: a float is its standard deviation;
        ``"abs:SIGMA"``, ``"snr:DB"`` or ``"rel:R"`` (``R`` times the largest
        ``|x|``, e.g. ``"rel:0.01"`` for 1%).
    seed : int, default 0
        Seed of the noise; row ``c`` uses ``seed + c``.
    method : {"auto", "expm", "modal", "rk"}, default "auto"
        Integration method.
    left, right : {"fixed", "free"}, default "fixed"
        How each end of the chain is held.

    Returns
    -------
    ndarray
        Shape ``(N,)`` for an int ``observe``, ``(len(observe), N)`` for a
        sequence.

    Raises
    ------
    ValueError
        Invalid input, naming the field.

    Examples
    --------
    >>> import numpy as np, springmass
    >>> x = springmass.simulate(20, defects=[("mass", 8, 5.0)], t=np.arange(0, 10, 0.5))
    >>> x.shape
    (20,)
    """
    single = not isinstance(observe, (list, tuple, np.ndarray))
    obs = [_count("observe", observe)] if single else [_count(f"observe[{i}]", o) for i, o in enumerate(observe)]
    if noise is None or isinstance(noise, str):
        noise_text = noise
    else:
        noise_text = "abs:" + repr(_real("noise", noise))
    out = _core.simulate(
        _chain(n, k, d, gamma, mass, defects, left, right, damping),
        _vector("t", t),
        observe=obs,
        observe_kind=_text("observe_kind", observe_kind),
        noise=noise_text,
        seed=_count("seed", seed),
        method=_text("method", method),
    )
    return out[0] if single else out


def response(
    s: Any,
    *,
    n: int,
    defects: Sequence[DefectLike] = (),
    d: Optional[float] = None,
    k: float = 1.0,
    gamma: float = 1.0,
    mass: float = 1.0,
    observe: int = 1,
    observe_kind: str = "displacement",
    left: str = "fixed",
    right: str = "fixed",
    damping: Optional[str] = None,
) -> Any:
    """The Laplace-domain response ``X_observe(s)`` of a chain.

    Closed form (Woodbury update of the uniform chain's Green's function),
    for the impulse ``gamma`` on mass 1.

    Parameters
    ----------
    s : complex or array_like
        Laplace variable(s), real or complex, any shape (``Re s >= 0``).
    n : int
        Number of masses.
    defects : sequence of Defect, (kind, at, value) or "kind:at:value", default ()
        The chain's defects.
    d, k, gamma, mass : float
        Uniform damping (0.1; 0 with another ``damping`` model), stiffness
        (1), impulse (1) and mass (1).
    damping : str, optional
        The damping model, as for :func:`simulate`.
    observe : int, default 1
        Observed mass (1-based).
    observe_kind : {"displacement", "velocity", "acceleration"}
        ``X(s)``, ``s X(s)`` or the acceleration's transform.
    left, right : {"fixed", "free"}, default "fixed"
        How each end of the chain is held.

    Returns
    -------
    ndarray or scalar
        Same shape as ``s``; float64 for real ``s``, complex128 for complex.

    Examples
    --------
    >>> import springmass
    >>> x = springmass.response([0.5, 1 + 2j], n=20, defects=[("mass", 8, 5.0), ("mass", 15, 2.0)])
    >>> x.dtype
    dtype('complex128')
    """
    a = np.asarray(s)
    if a.dtype.kind == "c":
        fn, a = _core.response_complex, a.astype(np.complex128)
    elif a.dtype.kind in "biuf":
        fn, a = _core.response_real, a.astype(np.float64)
    else:
        raise _invalid("s", _short(s), "real or complex numbers")
    out = fn(
        a,
        _chain(n, k, d, gamma, mass, defects, left, right, damping),
        observe=_count("observe", observe),
        observe_kind=_text("observe_kind", observe_kind),
    )
    return out[()] if a.ndim == 0 else out


def controls(
    n: int,
    *,
    t: Any,
    d: float = 0.1,
    k: float = 1.0,
    mass: float = 1.0,
    gamma: float = 1.0,
) -> Dict[str, np.ndarray]:
    """The suppression forces of section 3 at the times ``t``, exact.

    A uniform chain of ``n + 1`` masses is hit by ``gamma delta(t)`` on mass
    1. Theorem 3.1: the forces ``f`` on mass ``n`` and ``g`` on mass
    ``n - 1`` keep mass ``n + 1`` still and leave ``x_1`` unchanged.
    Corollary 3.2: ``f1`` on mass ``n`` alone keeps masses ``n`` and
    ``n + 1`` still.

    Parameters
    ----------
    n : int
        ``n >= 2``; the chain has ``n + 1`` masses.
    t : array_like, shape (N,)
        Times (finite); the forces are 0 for ``t <= 0``.
    d, k, mass, gamma : float
        Damping (0.1), stiffness (1), mass (1) and impulse (1).

    Returns
    -------
    dict of str to ndarray
        ``"f"``, ``"g"`` and ``"f1"``, each of shape ``(N,)``.

    Examples
    --------
    >>> import numpy as np, springmass
    >>> c = springmass.controls(4, t=np.linspace(0, 50, 11))
    >>> sorted(c)
    ['f', 'f1', 'g']
    """
    return dict(
        _core.controls(
            _count("n", n),
            _vector("t", t),
            k=_real("k", k),
            d=_real("d", d),
            mass=_real("mass", mass),
            gamma=_real("gamma", gamma),
        )
    )


@dataclass(frozen=True, eq=False)
class LaplaceTransform:
    """The transform of a sampled series (arrays in the shape of ``s``).

    Attributes
    ----------
    s : ndarray of complex
        The Laplace variables.
    value : ndarray of complex
        ``X(s)``.
    err : ndarray
        Total error estimate: ``err_disc + err_trunc + err_round``.
    err_disc, err_trunc, err_round : ndarray
        Discretisation, truncation (tail) and rounding parts.
    noise_std : ndarray or None
        Standard deviation of the transformed noise (with ``noise_sigma``).
    """

    s: np.ndarray
    value: np.ndarray
    err: np.ndarray
    err_disc: np.ndarray
    err_trunc: np.ndarray
    err_round: np.ndarray
    noise_std: Optional[np.ndarray]


def laplace(
    t: Any,
    x: Any,
    s: Any,
    *,
    degree: int = 7,
    noise_sigma: Optional[float] = None,
    tail: str = "envelope",
) -> LaplaceTransform:
    """Laplace transform ``X(s) = int x(t) exp(-s t) dt`` of a sampled series.

    Filon-type quadrature (exact for piecewise polynomials of ``degree``,
    whatever ``s``), with a per-``s`` error estimate. The GIL is released
    while it runs.

    Parameters
    ----------
    t : array_like, shape (N,)
        Sample times, strictly increasing (uniform or not; at least 4).
    x : array_like, shape (N,)
        Samples (finite).
    s : complex or array_like
        Where to evaluate (real or complex, any shape).
    degree : int, default 7
        Degree of the local interpolant, 3 to 9; the error estimate compares
        with ``degree - 2``.
    noise_sigma : float, optional
        White-noise standard deviation of the samples: adds ``noise_std``.
    tail : {"envelope", "modes", "zero"}, default "envelope"
        After the last sample: bound the tail by a fitted envelope, fit
        decaying modes and add their transform, or assume zero.

    Returns
    -------
    LaplaceTransform

    Examples
    --------
    >>> import numpy as np, springmass
    >>> t = np.linspace(0, 60, 601)
    >>> tr = springmass.laplace(t, np.exp(-t), [1.0, 2 + 1j])
    >>> bool(abs(tr.value[0] - 0.5) < 1e-8)
    True
    """
    sa = np.asarray(s)
    if sa.dtype.kind not in "biufc":
        raise _invalid("s", _short(s), "real or complex numbers")
    sc = np.ascontiguousarray(sa, dtype=np.complex128)
    raw = _core.laplace(
        _vector("t", t),
        _vector("x", x),
        sc.reshape(-1),
        degree=_count("degree", degree),
        noise_sigma=None if noise_sigma is None else _real("noise_sigma", noise_sigma),
        tail=_text("tail", tail),
    )

    def shaped(a: np.ndarray) -> np.ndarray:
        return a.reshape(sa.shape)

    return LaplaceTransform(
        s=sc,
        value=shaped(raw["value"]),
        err=shaped(raw["err"]),
        err_disc=shaped(raw["err_disc"]),
        err_trunc=shaped(raw["err_trunc"]),
        err_round=shaped(raw["err_round"]),
        noise_std=shaped(raw["noise_std"]) if "noise_std" in raw else None,
    )


# ---------------------------------------------------------------- locators


@dataclass(frozen=True, eq=False)
class Location:
    """One mass defect located by :func:`locate`.

    Attributes
    ----------
    position : int
        ``round(j)``, certain: ``|j - position| + 3 sigma + model_error < 1/2``.
    j : float
        The real position the relation gives.
    sigma : float
        Standard uncertainty of ``j`` from the data's error and rounding.
    model_error : float
        Bound on the relation's model error.
    s : float
        The ``s`` of the estimate (the largest one used).
    used_s : ndarray
        Every ``s`` the answer depends on.
    mass : float or None
        Estimated defect mass (unknown-mass and large-defect methods).
    raw_j : float or None
        ``j(s)`` before extrapolation (large-defect methods).
    method : str
        The locator used.
    """

    position: int
    j: float
    sigma: float
    model_error: float
    s: float
    used_s: np.ndarray
    mass: Optional[float]
    raw_j: Optional[float]
    method: str


def locate(
    t: Any = None,
    x: Any = None,
    *,
    n: int,
    s: Any = None,
    values: Any = None,
    err: Any = None,
    m: Optional[float] = None,
    method: Optional[str] = None,
    at: Optional[float] = None,
    noise_sigma: Optional[float] = None,
    d: float = 0.1,
    k: float = 1.0,
    mass: float = 1.0,
    gamma: float = 1.0,
) -> Location:
    """Locate one mass defect with the explicit relations of section 4.1.

    The data are a series ``x_1(t)`` (Laplace-transformed at ``s`` with its
    error estimate) or Laplace values ``X_1(s)`` with absolute errors. The
    locator solves its relation for a real position ``j`` at each ``s`` and
    accepts the answer only if the nearest integer is certain.

    Parameters
    ----------
    t, x : array_like, optional
        A measured series of mass 1 (give both, or ``values``).
    n : int
        Number of masses of the chain (fixed ends).
    s : array_like, optional
        Real ``s > 0``: where the series is transformed (default: 61 values
        from 1e-3 to 100), or the nodes of ``values``.
    values : array_like, optional
        ``X_1(s)`` at ``s`` (real).
    err : array_like, optional
        Absolute errors of ``values`` (default 0: exact up to rounding).
    m : float, optional
        The defect's mass if known (selects ``method="exact"``).
    method : {"exact", "asymptotic", "large", "large-paper", "unknown-mass"}, optional
        Default: ``"exact"`` with ``m``, else ``"unknown-mass"``.
    at : float, optional
        Use the datum at this ``s`` (default: the most certain one).
    noise_sigma : float, optional
        White-noise standard deviation of ``x`` (adds to each value's error).
    d, k, mass, gamma : float
        The chain's damping (0.1), stiffness (1), mass (1) and impulse (1).

    Returns
    -------
    Location

    Raises
    ------
    UnresolvableError
        No ``s`` resolves the defect at this error level, or the estimates
        disagree.
    ValueError
        Invalid input, naming the field.

    Examples
    --------
    >>> import springmass
    >>> s = [0.05, 0.1, 0.2, 0.4]
    >>> X = springmass.response(s, n=20, defects=[("mass", 3, 5.0)])
    >>> springmass.locate(n=20, s=s, values=X, m=5.0).position
    3
    """
    chain = _chain(n, k, d, gamma, mass, (), "fixed", "fixed")
    series = t is not None or x is not None
    if series and (t is None or x is None):
        raise _invalid("t" if t is None else "x", "None", "both t and x for a series")
    raw = _core.locate(
        chain,
        grid=None if s is None else _vector("s", s),
        t=_vector("t", t) if series else None,
        x=_vector("x", x) if series else None,
        values=None if values is None else _vector("values", values),
        err=None if err is None else _vector("err", err),
        method=None if method is None else _text("method", method),
        m=None if m is None else _real("m", m),
        at=None if at is None else _real("at", at),
        noise_sigma=None if noise_sigma is None else _real("noise_sigma", noise_sigma),
    )
    return Location(
        position=int(raw["position"]),
        j=float(raw["j"]),
        sigma=float(raw["sigma"]),
        model_error=float(raw["model_error"]),
        s=float(raw["s"]),
        used_s=raw["used_s"],
        mass=raw["mass"],
        raw_j=raw["raw_j"],
        method=raw["method"],
    )


# ---------------------------------------------------------------- scenes


@dataclass(frozen=True)
class Scene:
    """A reference chain of the paper: uniform parameters and defects.

    ``simulate(**scene.chain())`` and ``response(s, **scene.chain())``
    evaluate it.
    """

    name: str
    n: int
    k: float
    d: float
    gamma: float
    mass: float
    defects: Tuple[Defect, ...]

    def chain(self) -> Dict[str, Any]:
        """The keyword arguments of :func:`simulate` and :func:`response` for this chain."""
        return {
            "n": self.n,
            "k": self.k,
            "d": self.d,
            "gamma": self.gamma,
            "mass": self.mass,
            "defects": list(self.defects),
        }


def scene(name: str) -> Scene:
    """A reference scene of the paper by name.

    Parameters
    ----------
    name : str
        ``"P1"`` to ``"P4"`` (section 4.1-4.2) or ``"S1"`` to ``"S4"``
        (Table 1; ``"S3"`` is System 3: n = 20, masses 5 at 8 and 2 at 15).

    Returns
    -------
    Scene

    Examples
    --------
    >>> import springmass
    >>> springmass.scene("S3").defects
    (Defect(kind='mass', at=8, value=5.0), Defect(kind='mass', at=15, value=2.0))
    """
    raw = _core.scene(_text("name", name))
    return Scene(
        name=name.strip().upper(),
        n=int(raw["n"]),
        k=float(raw["k"]),
        d=float(raw["d"]),
        gamma=float(raw["gamma"]),
        mass=float(raw["mass"]),
        defects=tuple(Defect(kind, int(at), float(v)) for kind, at, v in raw["defects"]),
    )


@dataclass(frozen=True)
class ProfileValue:
    """One value of a fitted profile (see :func:`fit_profile`)."""

    kind: str
    at: int
    value: float
    se: float
    uniform: float
    visible: bool
    at_bound: bool
    depth: float


@dataclass(frozen=True)
class ProfileResult:
    """The answer of :func:`fit_profile`."""

    mode: str
    values: Tuple[ProfileValue, ...]
    visible_depth: Optional[float]
    change: float
    sigma: float
    sigma_estimated: bool
    chi2: float
    status: str
    message: str
    misfit: str
    summary: str

    @property
    def visible(self) -> Tuple[ProfileValue, ...]:
        """The values the data resolve (a ``change`` at two standard errors)."""
        return tuple(v for v in self.values if v.visible)

    def __str__(self) -> str:
        return self.summary


def fit_profile(
    t: Any,
    x: Any,
    *,
    n: int,
    profile: str = "masses",
    d: float = 0.1,
    noise: Union[str, float] = "auto",
    change: float = 0.1,
    penalty: Optional[float] = None,
    fit: Union[str, Sequence[str]] = (),
    gamma: float = 1.0,
    k: float = 1.0,
    mass: float = 1.0,
    left: str = "fixed",
    right: str = "fixed",
    observe: int = 1,
    observe_kind: str = "displacement",
    force: Any = None,
) -> ProfileResult:
    """Every mass, every spring, or both, of the chain from one record.

    The whole-profile inversion: every value free, fitted by bounded
    Levenberg-Marquardt with reciprocity gradients, regularised only as
    much as the noise needs (a continuation in a smooth L1 penalty on the
    deviation from the uniform value, stopped at the noise level); values
    the data cannot see (a ``change`` of the uniform value below two
    standard errors, typically deep in a damped chain) are reported as not
    visible; the visible ones are polished by the time-domain chi-square and
    carry standard errors. Same numbers as ``springmass fit --data FILE.csv
    --n N --profile MODE --json``. The GIL is released while it runs.

    Parameters
    ----------
    t, x : array_like, shape (N,)
        Sample times and the record (see :func:`fit`).
    n : int
        Number of masses.
    profile : {"masses", "springs", "both"}, default "masses"
        What is free.
    d : float, default 0.1
        Damping per mass (known, or a start with ``fit=("d",)``).
    noise : "auto" or float, default "auto"
        Standard deviation of the samples' noise, or estimated.
    change : float, default 0.1
        The relative change the visibility is stated for.
    penalty : float, optional
        A fixed penalty weight instead of the continuation.
    fit, gamma, k, mass, left, right, observe, observe_kind, force
        As in :func:`fit`.

    Returns
    -------
    ProfileResult
        Every value with its standard error and visibility, the depth up to
        which the data see a ``change``, the noise level, status and message.

    Raises
    ------
    ValueError
        Invalid input, named (``profile="all"``, ``change <= 0``, more free
        values than data, ...).

    Examples
    --------
    >>> import numpy as np, springmass
    >>> t = np.arange(0, 150, 0.25)
    >>> x = springmass.simulate(6, defects=[("mass", 2, 2.0)], t=t, noise="rel:1e-4", seed=1)
    >>> r = springmass.fit_profile(t, x, n=6)
    >>> [round(v.value, 2) for v in r.values]
    [1.0, 2.0, 1.0, 1.0, 1.0, 1.0]
    """
    tv, xv = _vector("t", t), _vector("x", x)
    fit_text = _fit_text(fit)
    noise_text = _noise_text(noise)
    raw = _core.fit_profile(
        tv,
        xv,
        n=_chain_size(n),
        profile=_text("profile", profile),
        d=_real("d", d),
        gamma=_real("gamma", gamma),
        fit=fit_text or None,
        noise=noise_text,
        k=_real("k", k),
        mass=_real("mass", mass),
        left=_text("left", left),
        right=_text("right", right),
        observe=_count("observe", observe),
        observe_kind=_text("observe_kind", observe_kind),
        force=None if force is None else _vector("force", force),
        change=_real("change", change),
        penalty=None if penalty is None else _real("penalty", penalty),
    )
    rep = json.loads(raw["report"])
    values = tuple(
        ProfileValue(
            kind=e["kind"],
            at=int(e["at"]),
            value=float(e["value"]),
            se=_nan(e["se"]),
            uniform=float(e["uniform"]),
            visible=bool(e["visible"]),
            at_bound=bool(e["at_bound"]),
            depth=float(e["depth"]),
        )
        for e in rep["elements"]
    )
    return ProfileResult(
        mode=rep["mode"],
        values=values,
        visible_depth=None if rep["visible_depth"] is None else float(rep["visible_depth"]),
        change=float(rep["change"]),
        sigma=float(rep["noise_sigma"]),
        sigma_estimated=bool(rep["noise_estimated"]),
        chi2=float(rep["chi2"]),
        status=rep["status"],
        message=rep["message"],
        misfit=rep["misfit"],
        summary=raw["summary"],
    )


def _record(i: int, rec: Any) -> Tuple[Any, Any]:
    """Record ``i`` of :func:`fit_many`: a ``(t, x)`` pair or a CSV path."""
    if isinstance(rec, str) or hasattr(rec, "__fspath__"):
        t, cols = read_csv(rec)
        if not cols:
            raise _invalid(f"records[{i}]", _short(rec), "a CSV with a value column")
        return t, next(iter(cols.values()))
    try:
        t, x = rec
    except (TypeError, ValueError):
        raise _invalid(f"records[{i}]", _short(rec), "a (t, x) pair of arrays or a CSV path") from None
    return t, x


def fit_many(
    records: Any,
    *,
    workers: Optional[int] = None,
    profile: Optional[str] = None,
    errors: str = "raise",
    **kwargs: Any,
) -> List[Any]:
    """Fit many records on a thread pool: :func:`fit` (or :func:`fit_profile`
    with ``profile=``) of each, with the same keyword arguments.

    The native fit releases the GIL, so the threads run in parallel on as
    many cores as ``workers``; the results are those of one call per record,
    in the order of ``records``, whatever the number of workers. Ctrl-C
    stops every running fit (their signal check needs the main thread, so
    the pool asks the library to stop them) and raises KeyboardInterrupt.
    For records on many machines, map the same call with Dask (see the
    guide's "Many records").

    Parameters
    ----------
    records : iterable
        ``(t, x)`` pairs of arrays, or paths of CSV records (their first
        value column, read by :func:`read_csv`).
    workers : int, optional
        Threads (>= 1) [default: the number of cores].
    profile : {"masses", "springs", "both"}, optional
        Fit the whole profile (:func:`fit_profile`) instead of defects.
    errors : {"raise", "return"}, default "raise"
        On a record that fails: raise its exception (the other fits still
        running are finished first), or put the exception in its place.
    **kwargs
        The keyword arguments of :func:`fit` or :func:`fit_profile` (``n``
        at least).

    Returns
    -------
    list
        One :class:`FitResult` (or :class:`ProfileResult`) per record.

    Examples
    --------
    >>> import numpy as np, springmass
    >>> t = np.arange(0, 100, 0.25)
    >>> recs = [(t, springmass.simulate(4, t=t, noise="rel:1e-3", seed=s)) for s in range(4)]
    >>> [r.k for r in springmass.fit_many(recs, n=4, workers=2)]
    [0, 0, 0, 0]
    """
    from concurrent.futures import ThreadPoolExecutor

    if errors not in ("raise", "return"):
        raise _invalid("errors", _short(errors), '"raise" or "return"')
    n_workers = (os.cpu_count() or 1) if workers is None else _count("workers", workers)
    if n_workers < 1:
        raise _invalid("workers", n_workers, ">= 1 (threads)")
    recs = [_record(i, r) for i, r in enumerate(records)]
    if profile is not None:
        kwargs["profile"] = profile
    fn = fit if profile is None else fit_profile

    def one(rec: Tuple[Any, Any]) -> Any:
        try:
            return fn(rec[0], rec[1], **kwargs)
        except Exception as e:
            if errors == "return":
                return e
            raise

    pool = ThreadPoolExecutor(max_workers=n_workers)
    futures = [pool.submit(one, r) for r in recs]
    try:
        out = [f.result() for f in futures]
    except KeyboardInterrupt:
        _core.cancel(True)
        pool.shutdown(wait=True, cancel_futures=True)
        _core.cancel(False)
        raise
    except BaseException:
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    pool.shutdown(wait=True)
    return out


@dataclass(frozen=True)
class SpectralResult:
    """Masses rebuilt from the modes of mass 1 (see :func:`spectral`)."""

    masses: np.ndarray
    consistency: float

    @property
    def resolved(self) -> bool:
        """``consistency < 1e-6``: the masses kept at least six digits."""
        return self.consistency < 1e-6


def spectral(
    omega: Any,
    residue: Any,
    *,
    k: float = 1.0,
    left: str = "fixed",
    right: str = "fixed",
) -> SpectralResult:
    """Every mass of a chain from the modes of mass 1 (inverse eigenvalue problem).

    Parameters
    ----------
    omega : array_like
        The natural frequencies (rad/s), every mode of the chain: as many
        as masses.
    residue : array_like
        The driving-point modal constants of mass 1 per unit impulse:
        ``X_1(s) / gamma = sum_j residue[j] / (s**2 + omega[j]**2)``.
    k : float
        The uniform spring constant.
    left, right : str
        ``"fixed"`` or ``"free"`` ends.

    Returns
    -------
    SpectralResult
        ``masses`` (m_1 first) and ``consistency``, about their relative
        error; above 1e-6 (``resolved`` false) part of the chain is beyond
        what the modes resolve in f64 (a light mass deep in the chain, a
        random profile).

    Examples
    --------
    >>> import springmass
    >>> r = springmass.spectral([1.0], [0.5])     # one mass on a wall spring
    >>> round(float(r.masses[0]), 12), r.resolved
    (2.0, True)
    """
    om = _vector("omega", omega)
    re = _vector("residue", residue)
    if om.shape != re.shape:
        raise _invalid("residue", f"{re.size} values", f"one per omega ({om.size})")
    raw = _core.spectral(om, re, k=_real("k", k), left=_text("left", left), right=_text("right", right))
    return SpectralResult(masses=np.asarray(raw["masses"]), consistency=float(raw["consistency"]))


def _modes_csv(modes: Any) -> str:
    """The CSV text of ``modes``: a path, or a sequence of dicts."""
    if isinstance(modes, (str, os.PathLike)):
        path = os.fspath(modes)
        if not os.path.isfile(path):
            raise _invalid("modes", path, "a regular CSV file, or a list of dicts (one per mode)")
        with open(path, encoding="utf-8-sig") as fh:
            return fh.read()
    if not isinstance(modes, (list, tuple)) or not modes:
        raise _invalid("modes", type(modes).__name__, "a path, or a non-empty list of dicts (one per mode)")
    masses = sorted({int(j) for m in modes for j in dict(m.get("phi", {}))})
    cols = ["frequency", "frequency_se", "damping", "damping_se"] + [f"phi_{j}" for j in masses]
    rows = []
    for i, m in enumerate(modes):
        if not isinstance(m, dict) or "frequency" not in m:
            raise _invalid(f"modes[{i + 1}]", m, 'a dict with "frequency" (Hz) and optional "phi": {mass: value}')
        phi = {int(j): v for j, v in dict(m.get("phi", {})).items()}
        cells = [m.get("frequency"), m.get("frequency_se"), m.get("damping"), m.get("damping_se")] + [
            phi.get(j) for j in masses
        ]
        rows.append(",".join("" if v is None else repr(float(v)) for v in cells))
    return ",".join(cols) + "\n" + "\n".join(rows) + "\n"


def update_from_modes(
    modes: Any,
    *,
    n: int,
    mass: float = 1.0,
    k: float = 1.0,
    d: float = 0.0,
    left: str = "fixed",
    right: str = "fixed",
    profile: str = "springs",
    hold_out: Sequence[int] = (),
    starts: int = 20,
    seed: int = 1,
    baseline: Any = None,
    modal_residual: str = "property",
    damping: Optional[str] = None,
    defects: Optional[str] = None,
    kinds: Optional[str] = None,
) -> Dict[str, Any]:
    """Update the storey springs (or masses) of a nominal chain from measured modes.

    The same as ``springmass fit --modes FILE``: the chain's modes are paired
    with the measured ones by MAC, frequencies and shapes (any scaling) are
    compared, every element is a factor of its nominal value with a standard
    error, and the factors the modes do not determine are said so.

    Parameters
    ----------
    modes : path or list of dict
        A CSV file (columns ``frequency`` in Hz, ``frequency_se``,
        ``damping``, ``phi_J``, ``phi_J_se``), or one dict per mode:
        ``{"frequency": 0.88, "phi": {1: -0.38, 2: -0.72}}``.
    n : int
        Number of masses (floors).
    mass, k, d : float
        The nominal uniform mass, storey stiffness and grounded damping.
    left, right : str
        ``"fixed"`` or ``"free"`` ends (a shear frame: ``right="free"``).
    profile : str
        ``"springs"``, ``"masses"`` or ``"both"``.
    hold_out : sequence of int
        Modes (1-based, increasing frequency) kept out of the fit, predicted only.
    starts, seed : int
        Seeded random starts beside the nominal one.
    baseline : str, path or dict, optional
        A measured or design profile as the nominal chain (as in
        :func:`fit`); the factors multiply its values, and ``n`` must agree.
    modal_residual : str
        ``"property"`` (the modal-property difference: frequencies and
        MAC-paired shapes) or ``"dynamic"`` (the modal dynamic residual:
        the equations of motion at the measured frequencies, the unmeasured
        shape components profiled out); ``--modal-residual`` of the CLI.
    damping : str, optional
        The nominal damping model, as ``--damping`` of the CLI
        (``"between:0.03"``: dampers between the storeys; by default the
        grounded ``d``). With a damped nominal chain the measured damping
        ratios (column ``damping``, dict key ``"damping"``) are fitted too.
    defects : str, optional
        ``"auto"``, ``"auto:K"`` or ``"K"``: search which elements changed
        instead of updating every one (``springmass fit --modes FILE
        --defects``); the report then has ``defects``, ``k_selection`` and
        ``runner_up``.
    kinds : str, optional
        With ``defects``: ``"spring"``, ``"mass"``, ``"damper"``, a comma
        list of them, or ``"any"`` (dampers included when the ratios are
        fitted); by default the springs, and the dampers when the ratios
        are fitted.

    Returns
    -------
    dict
        The report as ``springmass fit --modes FILE --json`` prints it
        (``status``, ``factors``, ``modes``, ...) and ``summary``, its text.

    Examples
    --------
    >>> import springmass
    >>> # the first mode of a uniform two-storey frame (k = m = 1), exact
    >>> r = springmass.update_from_modes(
    ...     [{"frequency": 0.09836316430834659, "phi": {1: 0.6180339887498949, 2: 1.0}}],
    ...     n=2, right="free")
    >>> [round(f["factor"], 6) for f in r["factors"]]
    [1.0, 1.0]
    """
    text = _modes_csv(modes)
    raw = _core.fit_modes(
        text,
        n=_chain_size(n),
        mass=_real("mass", mass),
        k=_real("k", k),
        d=_real("d", d),
        left=_text("left", left),
        right=_text("right", right),
        profile=_text("profile", profile),
        hold_out=[_count("hold_out", j) for j in hold_out],
        starts=_count("starts", starts),
        seed=_count("seed", seed),
        baseline=_baseline(baseline),
        modal_residual=_text("modal_residual", modal_residual),
        damping=None if damping is None else _text("damping", damping),
        defects=None if defects is None else _text("defects", defects),
        kinds=None if kinds is None else _text("kinds", kinds),
    )
    out = json.loads(raw["report"])
    out["summary"] = raw["summary"]
    return out


def fit_scene(scene: Any) -> Dict[str, Any]:
    """Fit a scene: the same as ``springmass fit --scene FILE --json``.

    A scene (TOML) names the true chain, the data (``exact``, ``simulated``,
    a ``series`` CSV, or ``modes``), the unknowns, the residual and the
    search; its data may hold several sensors (``observe = [1, 30, 60]``,
    one ``column`` each), several records (``path = ["hit1.csv",
    "hit2.csv"]``, or ``records = 3`` simulated) or measured modes (a modes
    CSV as ``path``, or ``modes``, ``floors``, ``frequency_noise`` and
    ``shape_noise`` simulated). Relative paths in the scene are taken from
    the working directory.

    Parameters
    ----------
    scene : str or path
        A scene file, or the scene's TOML text.

    Returns
    -------
    dict
        The report (``status``, ``message``, ``defects``, ``std_errors``,
        ``runners_up``, ...) and ``summary``, its text.

    Examples
    --------
    >>> import springmass
    >>> r = springmass.fit_scene('''
    ... [truth]
    ... n = 6
    ... right = "free"
    ... defects = [{ kind = "spring", at = 3, k = 0.7 }]
    ... [data]
    ... source = "modes"
    ... modes = 3
    ... floors = [2, 4, 6]
    ... [unknowns]
    ... kind = "spring"
    ... ''')
    >>> r["status"], r["defects"][0]["at"]
    ('converged', 3)
    """
    if isinstance(scene, os.PathLike) or (
        isinstance(scene, str) and "\n" not in scene and scene.strip().endswith(".toml")
    ):
        path = os.fspath(scene)
        try:
            with open(path, encoding="utf-8") as f:
                text = f.read()
        except OSError as e:
            raise _invalid("scene", path, f"a readable scene file ({e.strerror})") from None
    elif isinstance(scene, str):
        text = scene
    else:
        raise _invalid("scene", _short(scene), "a scene file or the scene's TOML text")
    raw = _core.fit_scene(text)
    out = json.loads(raw["report"])
    out["summary"] = raw["summary"]
    return out


def fit_ambient(
    data: Any,
    *,
    observe: Sequence[int],
    n: int,
    observe_kind: str = "displacement",
    mass: float = 1.0,
    k: float = 1.0,
    d: Optional[float] = None,
    left: str = "fixed",
    right: str = "fixed",
    ambient_on: Optional[Sequence[int]] = None,
    defects: Any = "auto",
    kinds: str = "springs",
    profile: bool = False,
    baseline: Any = None,
    ambient_band: Optional[Tuple[float, float]] = None,
) -> Dict[str, Any]:
    """Output-only (ambient) fit: which storey changed, from response records
    under an unknown broadband force.

    The same as ``springmass fit --data FILE --excitation ambient --observe
    1,15,30``: the channels' Welch cross-spectral matrix is compared with the
    chain's under white forces of an unknown level plus a sensor-noise floor
    per channel; the masses fix the absolute scale.

    Parameters
    ----------
    data : path or (t, channels)
        A CSV file (``t`` and one column per observed mass, in the order of
        ``observe``), or a pair of the times and a sequence of channels.
    observe : sequence of int
        The observed masses (1-based), one per channel.
    n : int
        Number of masses.
    observe_kind : str
        ``"displacement"``, ``"velocity"`` or ``"acceleration"``.
    mass, k : float
        The nominal (known) uniform mass and storey stiffness.
    d : float, optional
        The grounded damping; ``None`` (default): unknown, fitted.
    left, right : str
        ``"fixed"`` or ``"free"`` ends.
    ambient_on : sequence of int, optional
        The masses the white forces act on (default every mass).
    ambient_band : (float, float), optional
        Band-limited forces: a flat spectrum of the fitted level over
        ``(lo, hi)`` (angular frequencies, rad per unit time, as the report's
        ``band``) and none outside it (default: white). As
        ``--ambient-band LO:HI``.
    defects : "auto", "auto:K" or int
        The number of changed elements (default ``0..=2`` by BIC).
    kinds : str
        ``"springs"`` or ``"masses"``.
    profile : bool
        Every element a factor instead of the defect search.
    baseline : str, path or dict, optional
        A measured or design profile as the nominal chain (as in :func:`fit`).

    Returns
    -------
    dict
        The report as the CLI's ``--json`` prints it (``status``,
        ``factors``, ``d``, ``modes``, ...) and ``summary``, its text.

    Examples
    --------
    >>> import numpy as np
    >>> import springmass
    >>> t = np.arange(3000) * 0.5
    >>> try:  # a dead sensor is refused, naming its channel
    ...     springmass.fit_ambient((t, [np.sin(t), np.ones_like(t)]), observe=[1, 4], n=4)
    ... except ValueError as e:
    ...     print("channel 2 (mass 4)" in str(e))
    True
    """
    if isinstance(data, (str, os.PathLike)):
        t, cols = read_csv(data)
        channels = [np.asarray(v, dtype=float).tolist() for v in cols.values()]
    else:
        t, channels = data
        channels = [np.asarray(c, dtype=float).tolist() for c in channels]
    text = str(defects)
    if text == "auto":
        k_min, k_max = 0, 2
    elif text.startswith("auto:"):
        k_min, k_max = 0, _count("defects", int(text[5:]))
    else:
        k_min = k_max = _count("defects", int(text))
    raw = _core.fit_ambient(
        np.asarray(t, dtype=float).tolist(),
        channels,
        observe=[_count("observe", j) for j in observe],
        observe_kind=_text("observe_kind", observe_kind),
        n=_chain_size(n),
        mass=_real("mass", mass),
        k=_real("k", k),
        d=0.0 if d is None else _real("d", d),
        left=_text("left", left),
        right=_text("right", right),
        ambient_on=None if ambient_on is None else [_count("ambient_on", j) for j in ambient_on],
        k_min=k_min,
        k_max=k_max,
        kinds=_text("kinds", kinds),
        profile=bool(profile),
        fit_d=d is None,
        baseline=_baseline(baseline),
        ambient_band=None if ambient_band is None else _band(ambient_band),
    )
    out = json.loads(raw["report"])
    out["summary"] = raw["summary"]
    return out


def _band(band: Any) -> Tuple[float, float]:
    """A ``(lo, hi)`` pair of reals (the fit checks the range)."""
    try:
        lo, hi = band
    except (TypeError, ValueError):
        raise _invalid("ambient_band", band, "a pair (lo, hi) of angular frequencies") from None
    return _real("ambient_band", lo), _real("ambient_band", hi)


# ---------------------------------------------------------------- files


def read_csv(path: Any) -> Tuple[np.ndarray, Dict[str, np.ndarray]]:
    """Read a time series from a CSV file, as ``springmass fit --data`` does.

    A header ``t,<name>,...`` (units in brackets, a pandas index column and
    ``#`` comments accepted; ``,`` ``;`` or tab separated), strictly
    increasing finite times, finite values.

    Parameters
    ----------
    path : str or os.PathLike
        The file.

    Returns
    -------
    t : ndarray
        The times.
    columns : dict of str to ndarray
        The value columns by name, in file order.

    Raises
    ------
    OSError
        The file cannot be read.
    ValueError
        The file is not a valid time series (the message names the line or
        the column).

    Examples
    --------
    >>> import springmass
    >>> t, cols = springmass.read_csv("x1.csv")  # doctest: +SKIP
    >>> r = springmass.fit(t, cols["x1"], n=20)  # doctest: +SKIP
    """
    if isinstance(path, (bytes, bytearray, memoryview)):
        raise _invalid(
            "path",
            _short(bytes(path[:40])),
            "a file path as str or os.PathLike (not bytes: decode a path with os.fsdecode, or write CSV text to a file first)",
        )
    if not isinstance(path, str) and not hasattr(path, "__fspath__"):
        raise _invalid("path", _short(path), "a file path (str or os.PathLike)")
    path = os.fspath(path)
    if isinstance(path, bytes):
        path = os.fsdecode(path)
    raw = _core.read_csv(path)
    return raw["t"], dict(raw["columns"])
