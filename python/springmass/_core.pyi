"""Type stubs of the native module ``springmass._core`` (pyo3 + rust-numpy).

Private: use the functions of the ``springmass`` package, which check and
convert their arguments and wrap the results. Arrays arrive as float64
(complex128 for Laplace variables) numpy arrays of one dimension unless
stated; options arrive in the text forms of the command line.
"""

from os import PathLike
from typing import Any, Dict, List, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

class UnresolvableError(ValueError):
    """The data cannot resolve the requested result (a signal below the rounding or noise floor)."""

class NumericalError(RuntimeError):
    """A numerical method could not reach the requested accuracy."""

# {"n": int, "k": float, "d": float or None, "gamma": float, "mass": float,
#  "defects": list of "kind:at:value", "left": str, "right": str,
#  "damping": "MODEL[:P1[:P2]]" or None}
ChainDict = Dict[str, Any]

def fit(
    t: npt.NDArray[np.float64],
    x: npt.NDArray[np.float64],
    *,
    n: int,
    d: Optional[float] = None,
    gamma: Optional[float] = None,
    fit: Optional[str] = None,
    known: List[str] = ...,
    defects: Optional[str] = None,
    kinds: Optional[str] = None,
    slot_kinds: List[str] = ...,
    noise: Optional[str] = None,
    misfit: Optional[str] = None,
    method: Optional[str] = None,
    criterion: Optional[str] = None,
    seed: Optional[int] = None,
    max_evals: Optional[int] = None,
    k: Optional[float] = None,
    mass: Optional[float] = None,
    left: Optional[str] = None,
    right: Optional[str] = None,
    observe: Optional[int] = None,
    observe_kind: Optional[str] = None,
    force: Optional[npt.NDArray[np.float64]] = None,
    trigger: Optional[str] = None,
    noise_model: Optional[str] = None,
    nuisance: Optional[str] = None,
    damping: Optional[str] = None,
    force_window: Optional[str] = None,
    baseline: Union[str, "PathLike[str]", Dict[str, Any], None] = None,
    level: Optional[float] = None,
    prior_k: Optional[str] = None,
    prior_range: Optional[str] = None,
    uncertainty: Optional[bool] = None,
    exhaustive: Optional[bool] = None,
    effort: Optional[str] = None,
    sensors: List[int] = ...,
    sensor_kinds: List[str] = ...,
    more: List[npt.NDArray[np.float64]] = ...,
    record_t: List[npt.NDArray[np.float64]] = ...,
    record_x: List[npt.NDArray[np.float64]] = ...,
    record_force: List[Optional[npt.NDArray[np.float64]]] = ...,
) -> Dict[str, Any]:
    """The data-first fit: {"report": JSON text, "summary": str, "t", "observed", "model", "residual": ndarray}."""

def simulate(
    chain: ChainDict,
    t: npt.NDArray[np.float64],
    *,
    observe: List[int],
    observe_kind: str,
    noise: Optional[str],
    seed: int,
    method: str,
) -> npt.NDArray[np.float64]:
    """Rows of the observed masses at the uniform times t, shape (len(observe), len(t))."""

def response_real(
    s: npt.NDArray[np.float64], chain: ChainDict, *, observe: int, observe_kind: str
) -> npt.NDArray[np.float64]:
    """X(s) at real s (any shape)."""

def response_complex(
    s: npt.NDArray[np.complex128], chain: ChainDict, *, observe: int, observe_kind: str
) -> npt.NDArray[np.complex128]:
    """X(s) at complex s (any shape)."""

def controls(
    n: int, t: npt.NDArray[np.float64], *, k: float, d: float, mass: float, gamma: float
) -> Dict[str, npt.NDArray[np.float64]]:
    """{"f", "g", "f1"} at the times t."""

def laplace(
    t: npt.NDArray[np.float64],
    x: npt.NDArray[np.float64],
    s: npt.NDArray[np.complex128],
    *,
    degree: int,
    noise_sigma: Optional[float],
    tail: str,
) -> Dict[str, npt.NDArray[Any]]:
    """{"value", "err", "err_disc", "err_trunc", "err_round"[, "noise_std"]}."""

def locate(
    chain: ChainDict,
    *,
    grid: Optional[npt.NDArray[np.float64]],
    t: Optional[npt.NDArray[np.float64]] = None,
    x: Optional[npt.NDArray[np.float64]] = None,
    values: Optional[npt.NDArray[np.float64]] = None,
    err: Optional[npt.NDArray[np.float64]] = None,
    method: Optional[str] = None,
    m: Optional[float] = None,
    at: Optional[float] = None,
    noise_sigma: Optional[float] = None,
) -> Dict[str, Any]:
    """{"position", "j", "sigma", "model_error", "s", "used_s", "mass", "raw_j", "method"}."""

def scene(name: str) -> Dict[str, Any]:
    """{"n", "k", "d", "gamma", "mass", "defects": [(kind, at, value), ...]}."""

def read_csv(path: Union[str, "PathLike[str]"]) -> Dict[str, Any]:
    """{"t": ndarray, "columns": {name: ndarray}}."""

def spectral(
    omega: npt.NDArray[np.float64],
    residue: npt.NDArray[np.float64],
    *,
    k: float,
    left: str,
    right: str,
) -> Dict[str, Any]:
    """{"masses": ndarray, "consistency": float}."""

def fit_modes(
    modes: str,
    *,
    n: int,
    mass: float,
    k: float,
    d: float,
    left: str,
    right: str,
    profile: str,
    hold_out: List[int],
    starts: int,
    seed: int,
    baseline: Any = None,
    modal_residual: Optional[str] = None,
    damping: Optional[str] = None,
    defects: Optional[str] = None,
    kinds: Optional[str] = None,
) -> Dict[str, Any]:
    """{"report": JSON text, "summary": text}."""

def fit_scene(text: str) -> Dict[str, Any]:
    """{"report": JSON text, "summary": text}."""

def fit_ambient(
    t: List[float],
    channels: List[List[float]],
    *,
    observe: List[int],
    observe_kind: str,
    n: int,
    mass: float,
    k: float,
    d: float,
    left: str,
    right: str,
    ambient_on: Optional[List[int]],
    k_min: int,
    k_max: int,
    kinds: str,
    profile: bool,
    fit_d: bool,
    baseline: Any = None,
    ambient_band: Optional[Tuple[float, float]] = None,
) -> Dict[str, Any]:
    """{"report": JSON text, "summary": text}."""

def fit_profile(
    t: npt.NDArray[np.float64],
    x: npt.NDArray[np.float64],
    *,
    n: int,
    profile: str,
    d: Optional[float] = ...,
    gamma: Optional[float] = ...,
    fit: Optional[str] = ...,
    noise: Optional[str] = ...,
    k: Optional[float] = ...,
    mass: Optional[float] = ...,
    left: Optional[str] = ...,
    right: Optional[str] = ...,
    observe: Optional[int] = ...,
    observe_kind: Optional[str] = ...,
    force: Optional[npt.NDArray[np.float64]] = ...,
    change: Optional[float] = ...,
    penalty: Optional[float] = ...,
) -> Dict[str, Any]:
    """{"report": JSON text of the profile report, "summary": str}."""

def searches() -> List[Dict[str, Any]]:
    """[{"name", "aliases", "help", "kinds", "general_scene", "stochastic", "optimizer"}] (the search registry)."""

def cancel(stop: bool) -> None:
    """Ask every running fit to stop (True) or clear the request (False)."""
