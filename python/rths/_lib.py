"""ctypes declarations of librths's C API (include/rths/rths.h, docs/c-api.md)."""
import ctypes
import ctypes.util
import os

API_VERSION = 2  # RTHS_API_VERSION this package was written against


def error_type(msg_len):
    """rths_error (include/rths/core.h): a status code and a message of msg_len bytes. The length
    is the loaded library's (RTHS_ERROR_MSG_LEN as it was compiled, rths_api_sizeof), never a
    copy kept here: a smaller struct than the library's would be written past its end."""

    class Error(ctypes.Structure):
        _fields_ = [("code", ctypes.c_int), ("msg", ctypes.c_char * msg_len)]

    return Error


POINT_FN = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_int,
                            ctypes.POINTER(ctypes.c_char_p), ctypes.POINTER(ctypes.c_double))
CANCEL_FN = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p)


class FrfOptions(ctypes.Structure):
    """rths_api_frf_options."""

    _fields_ = [("out_dir", ctypes.c_char_p), ("strategy", ctypes.c_char_p),
                ("harmonics", ctypes.c_int), ("has_seed", ctypes.c_int),
                ("seed", ctypes.c_uint64), ("resume", ctypes.c_int),
                ("rig_uri", ctypes.c_char_p), ("on_point", POINT_FN),
                ("should_cancel", CANCEL_FN), ("user", ctypes.c_void_p),
                ("force", ctypes.c_int)]


class SimulateOptions(ctypes.Structure):
    """rths_api_simulate_options."""

    _fields_ = [("out_dir", ctypes.c_char_p), ("frequency_hz", ctypes.c_double),
                ("periods", ctypes.c_int), ("feedback", ctypes.c_int),
                ("delay_s", ctypes.c_double), ("harmonics", ctypes.c_int),
                ("target_dofs", ctypes.c_int), ("target_a", ctypes.POINTER(ctypes.c_double)),
                ("target_b", ctypes.POINTER(ctypes.c_double)), ("trace_periods", ctypes.c_int),
                ("has_seed", ctypes.c_int), ("seed", ctypes.c_uint64),
                ("rig_uri", ctypes.c_char_p), ("reset_fault", ctypes.c_int)]


def _candidates():
    """Where librths is looked for: RTHS_LIBRARY, the build tree of this checkout, the loader."""
    env = os.environ.get("RTHS_LIBRARY")
    if env:
        return [env]
    here = os.path.dirname(os.path.abspath(__file__))
    tree = os.path.join(os.path.dirname(os.path.dirname(here)), "build", "librths.so")
    found = ctypes.util.find_library("rths")
    return [p for p in (tree if os.path.exists(tree) else None, found, "librths.so.0") if p]


class LayoutError(OSError):
    """The loaded librths lays out a shared struct differently from this package."""


def _layout(lib, path):
    """Declares rths_error by the library's size (lib.Error) and checks every struct this package
    mirrors, field by field, against the library's sizeof/offsetof (rths.h, "the layout of the
    structs a caller allocates"); LayoutError naming the first difference."""
    lib.rths_api_sizeof.restype = ctypes.c_size_t
    lib.rths_api_sizeof.argtypes = [ctypes.c_char_p]
    lib.rths_api_offsetof.restype = ctypes.c_long
    lib.rths_api_offsetof.argtypes = [ctypes.c_char_p, ctypes.c_char_p]
    size = lib.rths_api_sizeof(b"rths_error")
    msg = lib.rths_api_offsetof(b"rths_error", b"msg")
    if size == 0 or msg < 0:
        raise LayoutError(f"{path} does not report the size of rths_error")
    lib.Error = error_type(size - msg)
    for ctype, cname in ((lib.Error, "rths_error"), (FrfOptions, "rths_api_frf_options"),
                         (SimulateOptions, "rths_api_simulate_options")):
        for field, _ in ctype._fields_:
            want = lib.rths_api_offsetof(cname.encode(), field.encode())
            got = getattr(ctype, field).offset
            if want != got:
                raise LayoutError(f"{path}: {cname}.{field} is at byte {want} in the library, "
                                  f"{got} in this package (python/rths/_lib.py): refusing to "
                                  "use it; rebuild the library or update the package")
        want, got = lib.rths_api_sizeof(cname.encode()), ctypes.sizeof(ctype)
        if want != got:
            raise LayoutError(f"{path}: {cname} has {want} bytes in the library, {got} in this "
                              "package (python/rths/_lib.py): refusing to use it; rebuild the "
                              "library or update the package")


def _declare(lib):
    c_int, c_char_p, c_void_p = ctypes.c_int, ctypes.c_char_p, ctypes.c_void_p
    err = ctypes.POINTER(lib.Error)
    handle = ctypes.POINTER(c_void_p)
    signatures = {
        "rths_api_version": (c_int, []),
        "rths_api_release": (c_char_p, []),
        "rths_api_config_load": (c_int, [c_char_p, ctypes.POINTER(c_char_p), c_int, handle, err]),
        "rths_api_config_free": (None, [c_void_p]),
        "rths_api_config_dofs": (c_int, [c_void_p]),
        "rths_api_config_get": (c_int, [c_void_p, c_char_p, ctypes.POINTER(c_void_p), err]),
        "rths_api_free": (None, [c_void_p]),
        "rths_api_model": (c_int, [c_void_p, c_char_p, handle, err]),
        "rths_api_chart": (c_int, [c_void_p, c_char_p, handle, err]),
        "rths_api_tune": (c_int, [c_void_p, ctypes.c_double, c_char_p, handle, err]),
        "rths_api_read_run": (c_int, [c_char_p, handle, err]),
        "rths_api_frf_options_default": (None, [ctypes.POINTER(FrfOptions)]),
        "rths_api_frf_available": (c_int, []),
        "rths_api_frf": (c_int, [c_void_p, ctypes.POINTER(FrfOptions), handle, err]),
        "rths_api_fidelity": (c_int, [c_void_p, c_char_p, handle, err]),
        "rths_api_simulate_options_default": (None, [ctypes.POINTER(SimulateOptions)]),
        "rths_api_simulate": (c_int, [c_void_p, ctypes.POINTER(SimulateOptions), handle, err]),
        "rths_result_text": (c_char_p, [c_void_p]),
        "rths_api_view_open": (c_int, [c_char_p, c_char_p, handle, err]),
        "rths_api_view_host": (c_char_p, [c_void_p]),
        "rths_api_view_host_is_loopback": (c_int, [c_void_p]),
        "rths_api_view_serve": (c_int, [c_void_p, err]),
        "rths_api_view_port": (c_int, [c_void_p]),
        "rths_api_view_stop": (None, [c_void_p]),
        "rths_api_controller_start": (c_int, [c_void_p, c_char_p, c_int, c_char_p, handle, err]),
        "rths_api_controller_port": (c_int, [c_void_p]),
        "rths_api_controller_view_port": (c_int, [c_void_p]),
        "rths_api_controller_stop": (c_int, [c_void_p, handle, err]),
        "rths_api_controller_latency": (c_int, [c_void_p, ctypes.c_double, handle, err]),
        "rths_result_table_count": (c_int, [c_void_p]),
        "rths_result_table_name": (c_char_p, [c_void_p, c_int]),
        "rths_result_rows": (c_int, [c_void_p, c_int]),
        "rths_result_columns": (c_int, [c_void_p, c_int]),
        "rths_result_column_name": (c_char_p, [c_void_p, c_int, c_int]),
        "rths_result_column": (ctypes.POINTER(ctypes.c_double), [c_void_p, c_int, c_int]),
        "rths_result_summary_json": (c_char_p, [c_void_p]),
        "rths_result_config_yaml": (c_char_p, [c_void_p]),
        "rths_result_dir": (c_char_p, [c_void_p]),
        "rths_result_free": (None, [c_void_p]),
    }
    for name, (restype, argtypes) in signatures.items():
        fn = getattr(lib, name)
        fn.restype = restype
        fn.argtypes = argtypes
    return lib


def load():
    """The loaded librths with its functions declared; OSError naming every place tried."""
    tried = []
    for path in _candidates():
        try:
            lib = ctypes.CDLL(path)
        except OSError as e:
            tried.append(f"{path} ({e})")
            continue
        lib.rths_api_version.restype = ctypes.c_int
        lib.rths_api_version.argtypes = []
        if lib.rths_api_version() != API_VERSION:
            raise OSError(f"{path} has C API version {lib.rths_api_version()}, "
                          f"this package needs {API_VERSION}")
        _layout(lib, path)
        _declare(lib)
        return lib
    raise OSError("librths not found: build it (make build) or set RTHS_LIBRARY; tried "
                  + "; ".join(tried))
