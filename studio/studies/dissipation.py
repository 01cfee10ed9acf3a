"""``brush-studio fit-dissipation SPINDOWN.csv``: fit the external dissipation of seed eq. 4.6.

A body on a hinge, spun and left to slow down on its own (no brush), follows

    d(omega)/dt = -k1 omega - k2 sign(omega)            (seed eq. 4.6 / E.1)

``k1`` (1/s) models air drag, ``k2`` (rad/s^2) the bearing's kinetic friction. Given the
measured spin-down as a (time, angle) series, the fit follows the seed's appendix F:

1. resample to a uniform grid (if needed) and low-pass filter the angle (zero-phase
   Butterworth, ``filtfilt``, around a least-squares cubic trend), because differentiating
   raw camera data amplifies its noise;
2. differentiate the filtered angle twice: omega(t) and alpha(t);
3. least squares ``alpha = -k1 omega - k2 sign(omega)`` over the samples where the body
   still turns (|omega| above a threshold, away from the filter's edge transients),
   with k1, k2 >= 0 as the seed requires.

It then checks the model the way fig. F.1b does: omega(t) integrated from the initial state
with the fitted k1, k2 against the filtered data. A second estimate refines k1, k2 (and the
initial angle and speed) by a non-linear least-squares fit of the closed-form angle
trajectory to the *raw* angle, which needs no differentiation; both are reported.

Outputs (``-o DIR``, default ``./fit-dissipation``): ``fit.json`` (k1, k2, their standard
errors, R^2, settings), ``fit.csv`` (the filtered series and the model), ``fit.h5`` (the same
arrays), ``fit.png`` (alpha against omega with the fitted line; omega against time, data and
model). The engine's hinge motion takes the fitted numbers directly:
``{"type": "hinge", "axis": [...], "k1": K1, "k2": K2}``.
"""
from __future__ import annotations

import csv
import json
import math
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from pydantic import Field

from . import api
from .options import StudyOptions
from ..exit_codes import EXIT_OK

DEFAULT_OUTPUT = "fit-dissipation"


class SpindownError(ValueError):
    """Bad spin-down data or fit settings (the message says what and what is allowed)."""


# ----------------------------------------------------------------------------- reading
_TIME_NAMES = ("time", "t", "time_s", "t_s")
_ANGLE_NAMES = ("angle", "theta", "angle_rad", "theta_rad", "phi", "orientation")


def read_spindown_csv(path, time_column: Optional[str] = None,
                      angle_column: Optional[str] = None) -> tuple[np.ndarray, np.ndarray]:
    """``(time, angle)`` from a CSV file: an optional header row, then numeric rows.

    Columns: ``time_column`` / ``angle_column`` (a header name or a 0-based index) when
    given; else the header's ``time``/``t`` and ``angle``/``theta`` columns; else the first
    two columns. Lines starting with ``#`` and empty lines are skipped."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise SpindownError(f"{path}: cannot read ({exc.strerror or exc})") from None
    rows = [r for r in csv.reader(line for line in text.splitlines()
                                  if line.strip() and not line.lstrip().startswith("#"))]
    if not rows:
        raise SpindownError(f"{path}: no data rows")
    header = None
    try:
        [float(v) for v in rows[0][:2]]
    except ValueError:
        header = [h.strip().lower() for h in rows[0]]
        rows = rows[1:]

    def pick(spec, names, default, what):
        if spec is not None:
            if str(spec).lstrip("-").isdigit():
                return int(spec)
            if header is None or spec.strip().lower() not in header:
                raise SpindownError(f"{path}: no column {spec!r} for the {what} "
                                    f"(columns: {header or 'no header row'})")
            return header.index(spec.strip().lower())
        if header is not None:
            for n in names:
                if n in header:
                    return header.index(n)
        return default

    it = pick(time_column, _TIME_NAMES, 0, "time")
    ia = pick(angle_column, _ANGLE_NAMES, 1, "angle")
    t, a = [], []
    for k, r in enumerate(rows, start=2 if header is not None else 1):
        try:
            t.append(float(r[it]))
            a.append(float(r[ia]))
        except (ValueError, IndexError):
            raise SpindownError(f"{path}: line {k}: expected numbers in columns {it} and "
                                f"{ia}, got {r}") from None
    return np.asarray(t, float), np.asarray(a, float)


# ----------------------------------------------------------------------------- model
def spindown_omega(t, omega0: float, k1: float, k2: float) -> np.ndarray:
    """omega(t) of eq. 4.6 from omega(0) = omega0: the closed form
    ``(omega0 + c) exp(-k1 t) - c``, c = k2 / k1 (``omega0 - k2 t`` for k1 = 0), until the
    body stops (then 0; it stays at rest since nothing drives it)."""
    t = np.asarray(t, float)
    s = 1.0 if omega0 >= 0 else -1.0
    w0 = abs(omega0)
    if k1 > 1e-12:
        c = k2 / k1
        w = (w0 + c) * np.exp(-k1 * t) - c
    else:
        w = w0 - k2 * t
    return s * np.clip(w, 0.0, None)


def spindown_angle(t, theta0: float, omega0: float, k1: float, k2: float) -> np.ndarray:
    """theta(t) of eq. 4.6 from theta(0) = theta0, omega(0) = omega0 (closed form: the
    integral of :func:`spindown_omega`; constant once the body stopped)."""
    t = np.asarray(t, float)
    s = 1.0 if omega0 >= 0 else -1.0
    w0 = abs(omega0)
    if k1 > 1e-12:
        c = k2 / k1
        t_stop = math.log1p(w0 / c) / k1 if c > 0 else math.inf
        tc = np.minimum(np.clip(t, 0.0, None), t_stop)
        turned = -(w0 + c) * np.expm1(-k1 * tc) / k1 - c * tc
    else:
        t_stop = w0 / k2 if k2 > 0 else math.inf
        tc = np.minimum(np.clip(t, 0.0, None), t_stop)
        turned = w0 * tc - 0.5 * k2 * tc * tc
    return theta0 + s * turned


def stop_time(omega0: float, k1: float, k2: float) -> float:
    """Time for eq. 4.6 to bring |omega0| to rest (inf when k2 = 0)."""
    w0 = abs(omega0)
    if k2 <= 0:
        return math.inf
    if k1 > 1e-12:
        return math.log1p(k1 * w0 / k2) / k1
    return w0 / k2


# ----------------------------------------------------------------------------- filtering
def uniform(time: np.ndarray, angle: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:
    """The series on a uniform grid: unchanged if it already is (steps within 1 %),
    else linearly interpolated at the median step. Returns ``(t, angle, resampled)``."""
    steps = np.diff(time)
    dt = float(np.median(steps))
    if np.all(np.abs(steps - dt) <= 0.01 * dt):
        return time, angle, False
    t = np.arange(time[0], time[-1] + 0.5 * dt, dt)
    t = t[t <= time[-1]]
    return t, np.interp(t, time, angle), True


def lowpass(signal: np.ndarray, dt: float, cutoff_hz: float, order: int = 4) -> np.ndarray:
    """Zero-phase Butterworth low-pass (``filtfilt``: no lag, the filter's order doubled).

    A least-squares cubic is taken out before filtering and added back: ``filtfilt`` pads
    the ends by odd reflection, which flips the sign of a spin-down's curvature (its
    deceleration) at each end, and the filtered derivatives then ring for about one cutoff
    period there (k1 off by 3 % on the synthetic tests); the residual has no such trend."""
    from numpy.polynomial import Polynomial
    from scipy.signal import butter, filtfilt

    nyquist = 0.5 / dt
    if not 0 < cutoff_hz < nyquist:
        raise SpindownError(f"cutoff = {cutoff_hz:g} Hz: must be in (0, {nyquist:g}) Hz, "
                            f"the Nyquist frequency of the data")
    signal = np.asarray(signal, float)
    x = np.arange(len(signal), dtype=float)
    trend = Polynomial.fit(x, signal, 3)(x)
    b, a = butter(order, cutoff_hz / nyquist)
    padlen = min(3 * max(len(a), len(b)) * 10, len(signal) - 1)
    return filtfilt(b, a, signal - trend, padlen=padlen) + trend


# ----------------------------------------------------------------------------- fit
@dataclass
class DissipationFit:
    """The result of :func:`fit_dissipation`. ``k1`` 1/s, ``k2`` rad/s^2 (appendix F method:
    filtered derivatives and linear least squares), with standard errors; ``refined_k1``,
    ``refined_k2``: the non-linear fit of the closed-form angle to the raw angle."""

    k1: float
    k2: float
    k1_stderr: float
    k2_stderr: float
    r_squared: float
    n_samples: int
    n_used: int
    cutoff_hz: float
    min_speed: float
    sample_interval: float
    resampled: bool
    omega0: float
    model_rms_omega: float  # rad/s, model against filtered data over the fitted span
    refined_k1: float = math.nan
    refined_k2: float = math.nan
    refined_omega0: float = math.nan
    refined_rms_angle: float = math.nan
    stop_time: float = math.nan
    warnings: list = field(default_factory=list)
    # arrays for the outputs (not in to_dict)
    t: np.ndarray = field(default=None, repr=False)
    angle: np.ndarray = field(default=None, repr=False)
    angle_filtered: np.ndarray = field(default=None, repr=False)
    omega: np.ndarray = field(default=None, repr=False)
    alpha: np.ndarray = field(default=None, repr=False)
    used: np.ndarray = field(default=None, repr=False)
    omega_model: np.ndarray = field(default=None, repr=False)

    def to_dict(self) -> dict:
        d = asdict(self)
        for k in ("t", "angle", "angle_filtered", "omega", "alpha", "used", "omega_model"):
            d.pop(k)
        return d


def fit_dissipation(time: Sequence[float], angle: Sequence[float], *,
                    cutoff_hz: Optional[float] = None, min_speed: Optional[float] = None,
                    refine: bool = True) -> DissipationFit:
    """Fit k1, k2 of seed eq. 4.6 to a spin-down (appendix F).

    ``cutoff_hz``: low-pass cutoff of the angle; default ``10 / duration`` (the spin-down's
    own time scale is the duration; ten times that keeps its shape while removing the
    high-frequency noise that differentiation amplifies), at most a fifth of the Nyquist
    frequency. ``min_speed`` (rad/s): samples slower than this are left out of the fit
    (near rest sign(omega) is undefined and the body may stick); default 5 % of the largest
    filtered speed."""
    time = np.asarray(time, float)
    angle = np.asarray(angle, float)
    if time.ndim != 1 or angle.shape != time.shape:
        raise SpindownError(f"time and angle must be 1-D and equally long "
                            f"(got {time.shape} and {angle.shape})")
    if len(time) < 20:
        raise SpindownError(f"{len(time)} samples: need at least 20")
    if not (np.all(np.isfinite(time)) and np.all(np.isfinite(angle))):
        raise SpindownError("time and angle must be finite numbers (found NaN or inf)")
    if np.any(np.diff(time) <= 0):
        k = int(np.flatnonzero(np.diff(time) <= 0)[0])
        raise SpindownError(f"time must increase strictly (row {k + 1}: {time[k]:g} -> "
                            f"{time[k + 1]:g})")
    warnings = []
    t, a, resampled = uniform(time, angle)
    if resampled:
        warnings.append("time steps were not uniform: resampled linearly at the median step")
    dt = float(t[1] - t[0])
    span = float(t[-1] - t[0])
    nyquist = 0.5 / dt
    if cutoff_hz is None:
        cutoff_hz = min(10.0 / span, 0.2 * nyquist)
    a_f = lowpass(a, dt, cutoff_hz)
    omega = np.gradient(a_f, dt)
    alpha = np.gradient(omega, dt)
    if min_speed is None:
        min_speed = 0.05 * float(np.max(np.abs(omega)))
    if min_speed < 0:
        raise SpindownError(f"min_speed = {min_speed:g}: must be >= 0")
    # leave out the filter's edge transients: one cutoff period at each end
    edge = int(math.ceil(1.0 / (cutoff_hz * dt)))
    used = np.abs(omega) > min_speed
    used[:edge] = False
    used[len(used) - edge:] = False
    # and everything from the first stop on (the body may stick; sign() is undefined there)
    slow = np.flatnonzero((np.abs(omega) <= min_speed) & (np.arange(len(t)) >= edge))
    if slow.size:
        used[slow[0]:] = False
    n_used = int(used.sum())
    if n_used < 10:
        raise SpindownError(
            f"only {n_used} samples turn faster than {min_speed:.3g} rad/s away from the "
            f"filter edges: give a longer spin-down, a lower --min-speed or a higher --cutoff")
    from scipy.optimize import lsq_linear

    A = np.column_stack([-omega[used], -np.sign(omega[used])])
    b = alpha[used]
    sol = lsq_linear(A, b, bounds=(0.0, np.inf))
    k1, k2 = (float(v) for v in sol.x)
    resid = b - A @ sol.x
    dof = max(1, n_used - 2)
    sigma2 = float(resid @ resid) / dof
    try:
        cov = sigma2 * np.linalg.inv(A.T @ A)
        k1_se, k2_se = float(math.sqrt(max(cov[0, 0], 0.0))), float(math.sqrt(max(cov[1, 1], 0.0)))
    except np.linalg.LinAlgError:
        k1_se = k2_se = math.nan
        warnings.append("omega does not vary enough to separate k1 from k2")
    ss_tot = float(np.sum((b - b.mean()) ** 2))
    r2 = 1.0 - float(resid @ resid) / ss_tot if ss_tot > 0 else math.nan
    for name, v in (("k1", k1), ("k2", k2)):
        if v == 0.0:
            warnings.append(f"{name} hit its bound 0 (the data show no such term)")
    # fig. F.1b: omega integrated from the first fitted state with the fitted model
    i0 = int(np.flatnonzero(used)[0])
    omega0 = float(omega[i0])
    model = np.full_like(omega, np.nan)
    model[i0:] = spindown_omega(t[i0:] - t[i0], omega0, k1, k2)
    i1 = int(np.flatnonzero(used)[-1]) + 1  # up to the last fitted sample (filter edges out)
    rms = float(np.sqrt(np.mean((model[i0:i1] - omega[i0:i1]) ** 2)))
    fit = DissipationFit(k1=k1, k2=k2, k1_stderr=k1_se, k2_stderr=k2_se, r_squared=r2,
                         n_samples=len(time), n_used=n_used, cutoff_hz=float(cutoff_hz),
                         min_speed=float(min_speed), sample_interval=dt, resampled=resampled,
                         omega0=omega0, model_rms_omega=rms,
                         stop_time=float(t[i0] + stop_time(omega0, k1, k2)),
                         warnings=warnings, t=t, angle=a, angle_filtered=a_f, omega=omega,
                         alpha=alpha, used=used, omega_model=model)
    if refine:
        _refine(fit, t[i0:] - t[i0], a[i0:], float(a_f[i0]))
    return fit


def _refine(fit: DissipationFit, t: np.ndarray, angle: np.ndarray, theta0: float) -> None:
    """Non-linear least squares of the closed-form angle trajectory to the raw angle,
    from the linear fit's values: (theta0, omega0, k1, k2) with k1, k2 >= 0."""
    from scipy.optimize import least_squares

    scale = max(abs(fit.omega0), 1e-9)

    def residual(p):
        return spindown_angle(t, p[0], p[1], p[2], p[3]) - angle

    x0 = [theta0, fit.omega0, max(fit.k1, 1e-6), max(fit.k2, 1e-6 * scale)]
    lo = [-np.inf, -np.inf, 0.0, 0.0]
    try:
        sol = least_squares(residual, x0, bounds=(lo, np.inf),
                            x_scale=[1.0, scale, max(fit.k1, 0.01), max(fit.k2, 0.01 * scale)])
    except ValueError as exc:
        fit.warnings.append(f"refined fit failed: {exc}")
        return
    fit.refined_omega0, fit.refined_k1, fit.refined_k2 = (float(v) for v in sol.x[1:])
    fit.refined_rms_angle = float(np.sqrt(np.mean(sol.fun ** 2)))


# ----------------------------------------------------------------------------- outputs
def write_outputs(fit: DissipationFit, out_dir: Path, source: str = "") -> dict[str, Path]:
    """Write fit.json, fit.csv, fit.h5 and fit.png into ``out_dir``; return the paths."""
    import h5py

    from engine.io.output_paths import check_output_dir

    # a folder, never a file, a device or a named pipe (created if missing)
    out_dir = check_output_dir(out_dir, "output folder", parents=True)
    paths = {k: out_dir / f"fit.{k}" for k in ("json", "csv", "h5", "png")}
    info = dict(fit.to_dict(), source=source,
                model="d(omega)/dt = -k1 omega - k2 sign(omega) (seed eq. 4.6)",
                units={"k1": "1/s", "k2": "rad/s^2", "omega": "rad/s", "time": "s"})
    from .run_files import write_json_atomic

    write_json_atomic(paths["json"], info)
    cols = ["time", "angle", "angle_filtered", "omega", "alpha", "used_in_fit", "omega_model"]
    tmp = paths["csv"].with_name(".fit.csv.tmp")
    with tmp.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        for row in zip(fit.t, fit.angle, fit.angle_filtered, fit.omega, fit.alpha,
                       fit.used.astype(int), fit.omega_model):
            w.writerow([f"{v:.9g}" if isinstance(v, float) else v for v in
                        (float(row[0]), float(row[1]), float(row[2]), float(row[3]),
                         float(row[4]), int(row[5]), float(row[6]))])
    tmp.replace(paths["csv"])
    with h5py.File(paths["h5"], "w") as h:
        for name, arr in zip(cols, (fit.t, fit.angle, fit.angle_filtered, fit.omega, fit.alpha,
                                    fit.used, fit.omega_model)):
            h.create_dataset(name, data=np.asarray(arr))
        h.attrs["fit"] = json.dumps(info, default=str)
    _plot(fit, paths["png"], source)
    return paths


def _plot(fit: DissipationFit, png: Path, source: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.5))
    u = fit.used
    ax1.plot(fit.omega[~u], fit.alpha[~u], ".", ms=2, color="0.75", label="not fitted")
    ax1.plot(fit.omega[u], fit.alpha[u], ".", ms=2, color="tab:blue", label="filtered data")
    w = np.linspace(min(0.0, fit.omega[u].min()), max(0.0, fit.omega[u].max()), 200)
    w = w[np.abs(w) > 0]
    ax1.plot(w, -fit.k1 * w - fit.k2 * np.sign(w), "r-",
             label=f"fit: k1 = {fit.k1:.4g} 1/s, k2 = {fit.k2:.4g} rad/s²")
    ax1.set_xlabel("angular velocity ω [rad/s]")
    ax1.set_ylabel("angular acceleration dω/dt [rad/s²]")
    ax1.set_title("(a) acceleration against velocity")
    ax1.grid(alpha=0.3)
    ax1.legend(fontsize=8)
    ax2.plot(fit.t, fit.omega, color="tab:blue", lw=1, label="filtered data")
    ax2.plot(fit.t, fit.omega_model, "r--", lw=1.2, label="eq. 4.6 with the fitted k1, k2")
    ax2.set_xlabel("time [s]")
    ax2.set_ylabel("ω [rad/s]")
    ax2.set_title("(b) velocity against time")
    ax2.grid(alpha=0.3)
    ax2.legend(fontsize=8)
    fig.suptitle(f"External dissipation fit (seed appendix F){': ' + source if source else ''}",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(png, dpi=120)
    plt.close(fig)


# ----------------------------------------------------------------------------- CLI
def register(subparsers) -> None:
    p = subparsers.add_parser(
        "fit-dissipation", help="fit k1, k2 of eq. 4.6 to a measured spin-down (time, angle)",
        description="Fit the external dissipation d(omega)/dt = -k1 omega - k2 sign(omega) "
                    "(seed eq. 4.6, appendix F) to a spin-down measured without the brush: "
                    "low-pass filter the angle, differentiate, least squares. Writes fit.json, "
                    "fit.csv, fit.h5 and fit.png into DIR.",
        epilog="Exit codes: 0 ok, 1 the fit failed, 2 bad input.")
    from .options import EXECUTION_OPTIONS
    from .study_command import set_command

    # no execution options: the fit runs no simulation
    set_command(p, run, Options, default_output=DEFAULT_OUTPUT, skip=EXECUTION_OPTIONS)


class Options(StudyOptions):
    """``brush-studio fit-dissipation``: the spin-down CSV to fit and how to read it (the
    execution options do not apply: the fit runs no simulation)."""

    spindown: str = Field(description="CSV with time [s] and angle columns (header optional: "
                                      "'time', 'angle'; else the first two columns)",
                          json_schema_extra={"positional": True, "metavar": "SPINDOWN.csv"})
    degrees: bool = Field(False, description="the angle column is in degrees")
    time_column: Optional[str] = Field(None, description="the time column's name or index",
                                       json_schema_extra={"metavar": "NAME|INDEX"})
    angle_column: Optional[str] = Field(None, description="the angle column's name or index",
                                        json_schema_extra={"metavar": "NAME|INDEX"})
    cutoff: Optional[float] = Field(None, gt=0, description="low-pass cutoff (default: 10 / "
                                                            "duration of the record)",
                                    json_schema_extra={"metavar": "HZ", "unit": "Hz"})
    min_speed: Optional[float] = Field(None, ge=0, description="fit only samples turning "
                                                               "faster than this (default 5% "
                                                               "of the top speed)",
                                       json_schema_extra={"metavar": "RAD_PER_S",
                                                          "unit": "rad/s"})


def _run_study(options: Options, out: Path) -> int:
    try:
        t, a = read_spindown_csv(options.spindown, options.time_column, options.angle_column)
        if options.degrees:
            a = np.radians(a)
        fit = fit_dissipation(t, a, cutoff_hz=options.cutoff, min_speed=options.min_speed)
    except SpindownError as exc:
        raise api.StudyInputError(str(exc)) from None
    paths = write_outputs(fit, out, source=str(options.spindown))
    print(f"k1 = {fit.k1:.6g} ± {fit.k1_stderr:.2g} 1/s      (refined: {fit.refined_k1:.6g})")
    print(f"k2 = {fit.k2:.6g} ± {fit.k2_stderr:.2g} rad/s^2  (refined: {fit.refined_k2:.6g})")
    print(f"R^2 = {fit.r_squared:.4f} over {fit.n_used} of {fit.n_samples} samples; "
          f"cutoff {fit.cutoff_hz:.3g} Hz; model omega(t) RMS error "
          f"{fit.model_rms_omega:.3g} rad/s")
    for w in fit.warnings:
        print(f"warning: {w}")
    print("Wrote: " + ", ".join(str(p) for p in paths.values()))
    print(f'For a hinge body: "motion": {{"type": "hinge", "axis": [0, 1, 0], '
          f'"k1": {fit.k1:.6g}, "k2": {fit.k2:.6g}}}')
    return EXIT_OK


# ``run(options, out_dir, *, progress=None, cancel=None)``: fit ``options.spindown`` and write
# the fit into ``out_dir``; a ``StudyResult`` (exit code 0 ok, 2 a spin-down that cannot be
# fitted)
run = api.study_run("fit-dissipation", _run_study)
