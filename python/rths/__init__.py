"""rths from Python: the iterative real-time hybrid testing toolkit's C library (librths) through
ctypes, with numpy arrays in and out (docs/python.md).

    import rths
    cfg = rths.Config.load("examples/four_storey.yaml", set={"split.mass_ratio": 0.33})
    m = rths.model(cfg)                  # m.modes["frequency_hz"], m.true_frf["x3_amplitude_m"]
    run = rths.read_run("out/demo/linear_p0.33")
    run.frf["amplitude_m"]               # the columns of frf.csv, as numpy arrays

Errors of the library raise rths.InputError (bad configuration or arguments; the message carries
FILE:LINE:COL for a configuration) or rths.RunError (numerics, I/O, rig fault).
"""
import ctypes
import json
import numbers
import os
import signal
import threading
import warnings

from . import _lib

# librths before numpy when rths is imported first: the BLAS both use then starts from the same
# state as in the CLI, so LAPACK-heavy results (the chart) usually match it to the last bit (import
# order or heap layout can otherwise move them by an ulp or so). A library that is not found is
# reported on first use, so `import rths` itself always works.
try:
    _LIB = _lib.load()
    _LOAD_ERROR = None
except OSError as e:
    _LIB, _LOAD_ERROR = None, e

import numpy as np  # noqa: E402

__all__ = ["Config", "Table", "Result", "RthsError", "InputError", "RunError", "Cancelled",
           "IncompleteRunWarning", "model", "chart", "tune", "fidelity", "simulate", "frf",
           "frf_available", "read_run", "View", "view", "Controller", "controller",
           "controller_latency", "library_release"]

def _c():
    global _LIB
    if _LIB is None:
        _LIB = _lib.load()  # raises OSError naming every place tried
    return _LIB


class RthsError(Exception):
    """An error reported by librths: .code is its status (1 failure, 2 bad input)."""

    def __init__(self, code, message):
        super().__init__(message)
        self.code = code
        self.message = message


class InputError(RthsError, ValueError):
    """Bad input (status 2): a configuration error says FILE:LINE:COL: key 'a.b': ..."""


class RunError(RthsError, RuntimeError):
    """The work could not be done (status 1): numerics, I/O, a rig fault."""


class Cancelled(KeyboardInterrupt):
    """Ctrl-C stopped an FRF test; .result is the run as saved (everything accepted is in it)."""

    def __init__(self, result):
        super().__init__("FRF test cancelled; accepted points saved in " + str(result.dir))
        self.result = result


class IncompleteRunWarning(UserWarning):
    """read_run found a folder without summary.json: the run did not finish (killed, or still
    running); the result holds what it had written (result.complete is False)."""


def _check(rc, err):
    if rc == 0:
        return
    message = err.msg.decode("utf-8", "replace")
    raise (InputError if rc == 2 else RunError)(rc, message)


def library_release():
    """The rths release of the loaded librths, e.g. '0.1.0'."""
    return _c().rths_api_release().decode()


def _yaml_value(value):
    """A Python value as the YAML flow text an override takes."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_yaml_value(v) for v in value) + "]"
    if isinstance(value, (float, np.floating)):
        return repr(float(value))
    return str(value)


def _scalar(text):
    """A YAML scalar's text as the value the configuration's getters read: bool, int, float or
    the text itself."""
    if text in ("true", "false"):
        return text == "true"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


class Config:
    """A test description (YAML) with overrides, checked on load. Use Config.load."""

    def __init__(self, handle, path, overrides):
        self._handle = handle
        self.path = path
        self.overrides = overrides

    @classmethod
    def load(cls, path=None, set=None):
        """Reads path (None: defaults only) with overrides: a dict {"split.mass_ratio": 0.33} or
        a list of "key=value" strings, applied in order, as the CLI's --set."""
        if set is None:
            overrides = []
        elif isinstance(set, dict):
            overrides = [f"{k}={_yaml_value(v)}" for k, v in set.items()]
        else:
            overrides = [str(s) for s in set]
        array = (ctypes.c_char_p * max(1, len(overrides)))(*[s.encode() for s in overrides])
        handle = ctypes.c_void_p()
        err = _c().Error()
        rc = _c().rths_api_config_load(None if path is None else str(path).encode(), array,
                                       len(overrides), ctypes.byref(handle), ctypes.byref(err))
        _check(rc, err)
        return cls(handle, path, overrides)

    def with_set(self, set):
        """A new Config: this one's file and overrides plus set (dict or list) applied after."""
        more = ([f"{k}={_yaml_value(v)}" for k, v in set.items()] if isinstance(set, dict)
                else [str(s) for s in set])
        return Config.load(self.path, self.overrides + more)

    def __getitem__(self, key):
        """The value of key ("split.mass_ratio") as configured, the file with the overrides: a
        number, bool or str for a scalar, a list (of lists) of floats for a list (matrix).
        KeyError for a key that is not set (its default applies, docs/config.md) or that holds a
        mapping."""
        c = _c()
        text = ctypes.c_void_p()
        err = c.Error()
        rc = c.rths_api_config_get(self._handle, str(key).encode(), ctypes.byref(text),
                                   ctypes.byref(err))
        if rc == 2:
            raise KeyError(err.msg.decode("utf-8", "replace"))
        _check(rc, err)
        try:
            value = ctypes.string_at(text).decode()
        finally:
            c.rths_api_free(text)
        if not value.startswith("["):
            return _scalar(value)
        floats = json.loads(value, parse_int=float)
        return floats

    def get(self, key, default=None):
        """self[key], or default when the key is not set."""
        try:
            return self[key]
        except KeyError:
            return default

    @property
    def dofs(self):
        """Degrees of freedom of the configured assembly."""
        return _c().rths_api_config_dofs(self._handle)

    def __del__(self):
        if getattr(self, "_handle", None) and _LIB is not None:
            _LIB.rths_api_config_free(self._handle)
            self._handle = None

    def __repr__(self):
        return f"rths.Config({self.path!r}, set={self.overrides!r})"


class Table(dict):
    """Columns of one CSV table as numpy arrays, in the file's order; also t.column_name."""

    def __init__(self, name, columns):
        super().__init__(columns)
        self.name = name

    @property
    def columns(self):
        return list(self.keys())

    @property
    def rows(self):
        return len(next(iter(self.values()))) if self else 0

    def __getattr__(self, name):
        try:
            return self[name]
        except KeyError:
            raise AttributeError(name) from None

    def to_pandas(self):
        """The table as a pandas DataFrame (columns in the file's order, integer columns as
        int64). Needs pandas (Debian: python3-pandas); ImportError naming it otherwise."""
        try:
            import pandas
        except ImportError as e:
            raise ImportError("Table.to_pandas() needs pandas (Debian: apt install "
                              "python3-pandas)") from e
        return pandas.DataFrame({name: self[name] for name in self.columns})

    def __repr__(self):
        return f"<rths.Table {self.name}: {self.rows} rows, columns {', '.join(self.columns)}>"


class Result:
    """A run's tables (by CSV name: result.frf, result.modes, result["true_frf"]), its summary
    (dict, from summary.json), config_yaml (text), dir (the run folder or None) and text (what the
    CLI's command prints, "" for the operations that print nothing). complete is False for a run
    folder without summary.json (a run that was killed or is still running: its summary is {} and
    its tables are what it had written, e.g. truth without frf)."""

    def __init__(self, tables, summary, config_yaml, dir, complete=True, text=""):
        self.tables = tables
        self.summary = summary
        self.config_yaml = config_yaml
        self.dir = dir
        self.complete = complete
        self.text = text

    def __getitem__(self, name):
        return self.tables[name]

    def __getattr__(self, name):
        tables = self.__dict__.get("tables", {})
        if name in tables:
            return tables[name]
        raise AttributeError(name)

    def __repr__(self):
        return f"<rths.Result {self.dir or '(no folder)'}: tables {', '.join(self.tables)}>"


# Columns that count or label (no SI unit in their names): numpy int64 arrays, and Python ints in
# on_point's rows, when every value is a finite integer (a NaN, "not measured", keeps the column
# float). The rest are doubles, as in the CSV files.
INTEGER_COLUMNS = frozenset({
    "point", "period", "mode", "evaluations", "iterations", "converged", "fold", "segment",
    "se_honest", "stable", "stable_experimental", "floquet_trustworthy", "harmonics_matched",
    # evaluations.csv
    "correction", "prediction", "jacobian", "step", "damped_step", "gain_probe", "accuracy_step",
    "iteration", "within_tolerance", "wait_periods", "average_periods", "steady", "fitted",
    "fit_fallback", "refused"})


def _typed(name, column):
    """column as int64 when name is an integer column and every value is a finite integer."""
    if (name in INTEGER_COLUMNS and np.all(np.isfinite(column))
            and np.array_equal(column, np.round(column))):
        return column.astype(np.int64)
    return column


def _typed_value(name, value):
    if name in INTEGER_COLUMNS and value == value and abs(value) != float("inf") \
            and value == int(value):
        return int(value)
    return value


def _take_result(handle):
    """Copies a C rths_result into a Result and frees it."""
    c = _c()
    try:
        tables = {}
        for t in range(c.rths_result_table_count(handle)):
            name = c.rths_result_table_name(handle, t).decode()
            rows = c.rths_result_rows(handle, t)
            columns = {}
            for k in range(c.rths_result_columns(handle, t)):
                data = c.rths_result_column(handle, t, k)
                column = (np.ctypeslib.as_array(data, shape=(rows,)).copy() if rows
                          else np.zeros(0))
                column_name = c.rths_result_column_name(handle, t, k).decode()
                columns[column_name] = _typed(column_name, column)
            tables[name] = Table(name, columns)
        text = c.rths_result_summary_json(handle).decode()
        folder = c.rths_result_dir(handle)
        folder = folder.decode() if folder else None
        try:
            summary = json.loads(text) if text.strip() else {}
        except ValueError as e:  # the library checks it; this is the last line of defence
            raise InputError(2, f"{folder}/summary.json: not valid JSON ({e})") from None
        config_yaml = c.rths_result_config_yaml(handle).decode()
        printed = c.rths_result_text(handle).decode()
        return Result(tables, summary, config_yaml, folder, complete=bool(text.strip()),
                      text=printed)
    finally:
        c.rths_result_free(handle)


def _run(fn, *args):
    handle = ctypes.c_void_p()
    err = _c().Error()
    rc = fn(*args, ctypes.byref(handle), ctypes.byref(err))
    _check(rc, err)
    return _take_result(handle)


def _config(cfg):
    if isinstance(cfg, Config):
        return cfg
    return Config.load(cfg)


def model(cfg, out=None):
    """Modes and analytic FRF of the true assembly (rths model): result.modes, result.true_frf,
    equal to the CLI's modes.csv and true_frf.csv. out: also write a run folder there."""
    cfg = _config(cfg)
    return _run(_c().rths_api_model, cfg._handle,
                None if out is None else os.fsencode(_path("out", out)))


def chart(cfg, out=None):
    """Stability chart of the delayed-feedback test (rths chart): result.chart, .boundary,
    .critical, equal to the CLI's CSV files. out: also write a run folder there."""
    cfg = _config(cfg)
    return _run(_c().rths_api_chart, cfg._handle,
                None if out is None else os.fsencode(_path("out", out)))


def tune(cfg, delay=None, out=None):
    """PD and grounding gains from the model (rths tune), every interface DoF: result.loop (the
    configured and the tuned loop's gain, phase and sensitivity, equal to the CLI's loop.csv),
    result.summary (summary.json: "current", "tuned", their margins; with several interface DoFs
    "loops" per DoF and the coupled loop's "coupled_gain_margin_db") and
    result.summary["tuned_yaml"], the keys to paste. delay: the physical loop's transport delay, s,
    in [0, 0.1] (a lab's measured delay, as --delay); None: the configured one as the virtual rig
    holds it. out: also write a run folder there (with tuned.yaml). No gains meeting the rule
    raise RunError."""
    cfg = _config(cfg)
    if delay is not None:
        delay = float(delay)
        if not 0 <= delay <= 0.1:
            raise InputError(2, f"delay {delay!r} s: must be in [0, 0.1]")
    return _run(_c().rths_api_tune, cfg._handle, -1.0 if delay is None else delay,
                None if out is None else os.fsencode(_path("out", out)))


def fidelity(cfg, out=None):
    """What the numerical substructure's integration scheme does to the hybrid test (rths
    fidelity): result.fidelity (frequency_hz, true_amplitude_m, <scheme>_amplitude_m, equal to the
    CLI's fidelity.csv; on a sparse model the real-time reduction's interface FRF error instead,
    docs/config/fidelity.md), result.summary["curves"][name] with each curve's peak_hz,
    peak_amplitude_m and peak_error_percent, result.text the table the CLI prints. out: also write
    a run folder there."""
    cfg = _config(cfg)
    return _run(_c().rths_api_fidelity, cfg._handle,
                None if out is None else os.fsencode(_path("out", out)))


def _target(target):
    """target as (dofs, harmonics, a, b): one list [A1, B1, A2, B2, ...] (m) for one interface
    DoF, or a list of such lists, one per interface DoF (as --target's ';'-separated lists)."""
    rows = np.asarray(target, dtype=float)
    if rows.ndim == 1:
        rows = rows[np.newaxis, :]
    if rows.ndim != 2 or rows.shape[1] == 0 or rows.shape[1] % 2:
        raise InputError(2, f"target={target!r}: give pairs A_k, B_k per harmonic, one list per "
                            "interface DoF")
    if not np.all(np.isfinite(rows)):
        raise InputError(2, f"target={target!r}: every coefficient must be finite")
    dofs, harmonics = rows.shape[0], rows.shape[1] // 2
    a = np.ascontiguousarray(rows[:, 0::2].reshape(-1))
    b = np.ascontiguousarray(rows[:, 1::2].reshape(-1))
    return dofs, harmonics, a, b


def simulate(cfg, frequency, periods, target=None, mode="iterative", delay=None,
             trace_periods=None, seed=None, rig=None, reset_fault=False, out=None):
    """One hybrid test (rths simulate). mode "iterative": the physical interface controlled to
    the fixed target x*(t) = sum_k A_k cos(k w t) + B_k sin(k w t) (target: [A1, B1, ...] in m,
    or one such list per interface DoF) for `periods` forcing periods at `frequency` Hz, then a
    trace of trace_periods more (default min(periods, 5)). mode "feedback": the conventional test
    with the loop closed, through the rig, or with delay (s) the seed's pure-delay model.
    result.coefficients (one row per period: phys_a1_m, num_a1_m, ...) and result.trace equal the
    CLI's CSV files; result.summary its summary.json; result.text what it prints. rig:
    "tcp://HOST:PORT" of a controller process. out: also write a run folder there."""
    if mode not in ("iterative", "feedback"):
        raise InputError(2, f"mode={mode!r}: iterative or feedback")
    c = _c()
    o = _lib.SimulateOptions()
    c.rths_api_simulate_options_default(ctypes.byref(o))
    try:
        o.frequency_hz = float(frequency)
    except (TypeError, ValueError):
        raise InputError(2, f"frequency={frequency!r}: expected a number (Hz)") from None
    o.periods = _integer("periods", periods, 1, 100000)
    o.feedback = 1 if mode == "feedback" else 0
    keep = None
    if target is not None:
        if mode == "feedback":
            raise InputError(2, "target: not used in feedback mode (the target is the numerical "
                                "interface displacement itself)")
        o.target_dofs, o.harmonics, a, b = _target(target)
        keep = (a, b)  # alive until the call returns
        o.target_a = a.ctypes.data_as(ctypes.POINTER(ctypes.c_double))
        o.target_b = b.ctypes.data_as(ctypes.POINTER(ctypes.c_double))
    elif mode == "iterative":
        raise InputError(2, "target: required in iterative mode ([A1, B1, ...], m)")
    if delay is not None:
        o.delay_s = float(delay)
        if not o.delay_s > 0:
            raise InputError(2, f"delay={delay!r}: must be > 0 s")
    if trace_periods is not None:
        o.trace_periods = _integer("trace_periods", trace_periods, 1, 1000)
    if seed is not None:
        o.has_seed, o.seed = 1, _integer("seed", seed, 0, 2**64 - 1)
    if rig is not None:
        o.rig_uri = rig.encode()
    o.reset_fault = 1 if reset_fault else 0
    if out is not None:
        o.out_dir = os.fsencode(_path("out", out))
    cfg = _config(cfg)
    result = _run(c.rths_api_simulate, cfg._handle, ctypes.byref(o))
    del keep
    return result


def read_run(dir):
    """A run folder: every CSV rths wrote there as a Table (result.frf["amplitude_m"]; a user's
    own CSV files are not read), summary, config_yaml. A folder that is not a run folder, or whose
    summary.json is damaged, raises InputError. A run that did not finish (no summary.json: killed,
    or still running) gives result.complete False and an IncompleteRunWarning."""
    result = _run(_c().rths_api_read_run, os.fsencode(_path("dir", dir)))
    if not result.complete:
        warnings.warn(IncompleteRunWarning(
            f"{result.dir}: no summary.json, the run did not finish (killed, or still running); "
            f"tables read: {', '.join(result.tables) or 'none'}; an FRF run continues with "
            "rths.frf(..., resume=True)"), stacklevel=2)
    return result


class View:
    """The web view of a run or campaign folder being served (rths view, docs/view.md): .url,
    .host, .port, .loopback (False: the page, which has no authentication, is reachable from other
    machines). stop() closes every connection; a with-block stops it however it ends."""

    def __init__(self, handle):
        c = _c()
        self._handle = handle
        self.host = c.rths_api_view_host(handle).decode()
        self.loopback = bool(c.rths_api_view_host_is_loopback(handle))
        self.port = c.rths_api_view_port(handle)
        host = f"[{self.host}]" if ":" in self.host else self.host
        self.url = f"http://{host}:{self.port}/"

    def stop(self):
        if self._handle:
            _c().rths_api_view_stop(self._handle)
            self._handle = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()

    def __del__(self):
        self.stop()


def view(dir, listen="127.0.0.1:0"):
    """Serves the web view of the run (or campaign) folder dir on listen ("ADDR:PORT",
    "[v6]:PORT"; port 0: a free one, the default) until .stop(); returns a View (its .url).
    A bad folder or address raises InputError naming it."""
    c = _c()
    handle = ctypes.c_void_p()
    err = c.Error()
    _check(c.rths_api_view_open(os.fsencode(_path("dir", dir)), listen.encode(),
                                ctypes.byref(handle), ctypes.byref(err)), err)
    # the server's threads inherit this thread's mask: Ctrl-C stays with Python's main thread
    rc = _threads_without_signals(lambda: c.rths_api_view_serve(handle, ctypes.byref(err)))
    if rc:
        c.rths_api_view_stop(handle)
        _check(rc, err)
    return View(handle)


def _threads_without_signals(start):
    """start() with SIGINT and SIGTERM blocked in this thread, so threads it creates (which inherit
    the mask) leave Ctrl-C to Python's main thread; the mask is restored however start ends."""
    masked = hasattr(signal, "pthread_sigmask")
    if masked:
        old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    try:
        return start()
    finally:
        if masked:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)


class Controller:
    """A real-time controller serving in this process (rths controller, docs/protocol.md): its
    paced loop and network thread run until stop(). .host, .port (the one chosen for port 0),
    .rig ("tcp://HOST:PORT", what rths.frf and rths.simulate take as rig=), .view_url (its web
    page, None without one). stop() disarms the actuator, closes the connection and returns the
    loop's statistics (dict: samples, overruns, lateness_p50_s, lateness_p99_s, worst_lateness_s,
    step_mean_s, step_max_s, ...); a with-block stops it however the block ends."""

    def __init__(self, handle, host):
        c = _c()
        self._handle = handle
        self.host = host
        self.port = c.rths_api_controller_port(handle)
        bracketed = f"[{host}]" if ":" in host else host
        self.rig = f"tcp://{bracketed}:{self.port}"
        view_port = c.rths_api_controller_view_port(handle)
        self.view_url = f"http://{bracketed}:{view_port}/" if view_port >= 0 else None
        self.stats = None

    def stop(self):
        """Stops the controller (once; later calls return the same statistics)."""
        if self._handle:
            c = _c()
            handle, self._handle = self._handle, None
            stats = ctypes.c_void_p()
            err = c.Error()
            _check(c.rths_api_controller_stop(handle, ctypes.byref(stats), ctypes.byref(err)), err)
            self.stats = _take_result(stats).summary
        return self.stats

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()

    def __del__(self):
        if getattr(self, "_handle", None) and _LIB is not None:
            _LIB.rths_api_controller_stop(self._handle, None, None)
            self._handle = None

    def __repr__(self):
        state = "stopped" if self._handle is None else "serving"
        return f"<rths.Controller {self.rig} ({state})>"


def _listen_host(listen):
    """The address part of "ADDR:PORT" or "[v6]:PORT"."""
    if listen.startswith("[") and "]" in listen:
        return listen[1:listen.index("]")]
    return listen.rsplit(":", 1)[0]


def controller(cfg, listen="127.0.0.1:0", site=None, view=None):
    """Starts the real-time controller of the test cfg (rths controller: the numerical
    substructure, the simulated plant or the io section's plug-in, the server section) serving
    one host on listen ("ADDR:PORT", "[v6]:PORT"; port 0, the default: a free one) and returns a
    Controller (its .rig for rths.frf/rths.simulate); it runs until .stop(). site: the 1-based
    site of a multi-site test (rig.sites). view: "ADDR:PORT" of the process's web page. Bad input
    raises InputError before anything runs."""
    if not isinstance(listen, str):
        raise InputError(2, f"listen={listen!r}: expected 'ADDR:PORT'")
    if view is not None and not isinstance(view, str):
        raise InputError(2, f"view={view!r}: expected 'ADDR:PORT'")
    site = 0 if site is None else _integer("site", site, 1, 2**31 - 1)
    cfg = _config(cfg)
    c = _c()
    handle = ctypes.c_void_p()
    err = c.Error()
    rc = _threads_without_signals(lambda: c.rths_api_controller_start(
        cfg._handle, listen.encode(), site, None if view is None else view.encode(),
        ctypes.byref(handle), ctypes.byref(err)))
    _check(rc, err)
    return Controller(handle, _listen_host(listen))


def controller_latency(seconds, cfg=None):
    """The machine's latency test (rths controller --latency-test): the controller's paced loop
    alone for `seconds` at controller.sample_rate_hz (cfg: a test description, None: the
    defaults). result.summary: samples, sample_rate_hz, overruns, lateness_p50_s ...
    lateness_p999_s, worst_lateness_s (s), sched_fifo, memory_locked, pinned; result.text the line
    the command prints. Blocks for the duration."""
    try:
        seconds = float(seconds)
    except (TypeError, ValueError):
        raise InputError(2, f"seconds={seconds!r}: expected a number") from None
    c = _c()
    handle = None if cfg is None else _config(cfg)._handle
    return _run(c.rths_api_controller_latency, handle, seconds)


def _path(name, value):
    """A folder argument as str, refusing None (str(None) would be a folder called 'None')."""
    if value is None:
        raise InputError(2, f"{name}: a folder is required, got None")
    if not isinstance(value, (str, bytes, os.PathLike)):
        raise InputError(2, f"{name}: expected a path (str or os.PathLike), got "
                            f"{type(value).__name__}")
    return os.fsdecode(value)


def _integer(name, value, lo, hi):
    """value as an int in [lo, hi]; InputError otherwise (ctypes would wrap it silently: seed
    2**64 was seed 0, harmonics 2**40 was 0, 'the configuration's')."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise InputError(2, f"{name}={value!r}: expected an integer")
    if not lo <= int(value) <= hi:
        raise InputError(2, f"{name}={value}: must be in [{lo}, {hi}]")
    return int(value)


def frf_available():
    """True when the loaded librths can run FRF tests."""
    return bool(_c().rths_api_frf_available())


class _Callbacks:
    """The per-point callback and the cancel flag of one FRF run."""

    def __init__(self, on_point):
        self.on_point = on_point
        self.error = None
        self.cancelled = False

    def point(self, user, n, names, row):
        if self.on_point is None or self.error is not None:
            return 0 if self.error is None else 1
        try:
            self.on_point({name: _typed_value(name, row[i])
                           for i, name in ((i, names[i].decode()) for i in range(n))})
            return 0
        except BaseException as e:  # noqa: B036 - re-raised after the run is saved
            self.error = e
            return 1

    def should_cancel(self, user):
        return 1 if self.cancelled or self.error is not None else 0


def _discard_earlier_run(out):
    """Makes out ready for a new FRF run over an earlier one (frf's overwrite=True): its journal
    and live state go, so the run starts afresh instead of asking for resume; the earlier run's
    other files are replaced by the run itself (the ones it listed in .rths-files are removed
    when it opens the folder, report.h), a user's files stay, run.log keeps its history. A run
    still writing there (run.lock held) is refused."""
    import fcntl
    journal = os.path.join(out, "journal.jsonl")
    if not os.path.exists(journal):
        return
    lock = os.path.join(out, "run.lock")
    fd = os.open(lock, os.O_RDONLY) if os.path.exists(lock) else None
    try:
        if fd is not None:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                raise InputError(2, f"{out}: a run is writing there now (run.lock is held); "
                                    "overwrite=True replaces only a finished or stopped run") \
                    from None
        for name in ("journal.jsonl", "live.json"):
            try:
                os.remove(os.path.join(out, name))
            except FileNotFoundError:
                pass
    finally:
        if fd is not None:
            os.close(fd)


def _python_words(message):
    """The run module's messages name the command's options (--resume, --out); a Python caller
    passed frf's arguments."""
    return (message.replace("continue it with --resume, or choose another --out",
                            "continue it with resume=True, start a new run there with "
                            "overwrite=True, or choose another out")
            .replace("--resume: ", "resume=True: "))


def frf(cfg, out, seed=None, strategy=None, harmonics=None, resume=False, rig=None,
        on_point=None, force=False, overwrite=False):
    """The iterative hybrid test with continuation (rths frf) into the run folder out.

    Returns a Result whose table frf holds frf.csv's columns. on_point(row) is called with each
    accepted point's frf.csv row as a dict; if it raises, the run stops cleanly (everything
    accepted saved) and the exception is raised again. Ctrl-C stops the run the same way and
    raises rths.Cancelled carrying the saved result. A test whose true response exceeds the
    rig's displacement limit raises InputError unless force=True. A folder holding an earlier
    FRF run raises InputError (continue it with resume=True) unless overwrite=True, which starts
    a new run there."""
    out = _path("out", out)
    # checked here, before ctypes narrows them (the library checks harmonics' upper limit)
    harmonics = None if harmonics is None else _integer("harmonics", harmonics, 1, 2**31 - 1)
    seed = None if seed is None else _integer("seed", seed, 0, 2**64 - 1)
    if overwrite and resume:
        raise InputError(2, "overwrite=True and resume=True: choose one (overwrite starts afresh, "
                            "resume continues the earlier run)")
    cfg = _config(cfg)
    if overwrite:
        _discard_earlier_run(out)
    c = _c()
    o = _lib.FrfOptions()
    c.rths_api_frf_options_default(ctypes.byref(o))
    o.out_dir = os.fsencode(out)
    if strategy is not None:
        o.strategy = strategy.encode()
    if harmonics is not None:
        o.harmonics = harmonics
    if seed is not None:
        o.has_seed, o.seed = 1, seed
    o.resume = 1 if resume else 0
    o.force = 1 if force else 0
    if rig is not None:
        o.rig_uri = rig.encode()
    cb = _Callbacks(on_point)
    o.on_point = _lib.POINT_FN(cb.point)
    o.should_cancel = _lib.CANCEL_FN(cb.should_cancel)
    previous = None
    if threading.current_thread() is threading.main_thread():
        def interrupt(signum, frame):
            cb.cancelled = True
        previous = signal.signal(signal.SIGINT, interrupt)
    try:
        result = _run(c.rths_api_frf, cfg._handle, ctypes.byref(o))
    except RthsError as e:
        raise type(e)(e.code, _python_words(e.message)) from None
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
    if cb.error is not None:
        raise cb.error
    if cb.cancelled:
        raise Cancelled(result)
    return result
