"""Argument checks shared by the public functions: one place for the type contract.

Every public function raises ``ValueError`` for a bad value (out of range, wrong shape,
unknown name), ``TypeError`` for a value of the wrong kind (complex radiance, a dict where
a number is expected) and ``OSError`` for files; never ``OverflowError`` or
``RecursionError``. Messages name the Python parameter.
"""

import numpy as np

U64_MAX = 2**64 - 1


def uint(name, value, minimum=0, maximum=U64_MAX):
    """``value`` as a Python int in ``[minimum, maximum]`` (default: a 64-bit unsigned
    integer); a bool, a float or anything else is a ``TypeError``, an int out of range a
    ``ValueError`` naming ``name``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"invalid parameter `{name}` = {value!r}: an integer")
    v = int(value)
    if v < minimum or v > maximum:
        top = "2**64 - 1" if maximum == U64_MAX else str(maximum)
        raise ValueError(f"invalid parameter `{name}` = {v}: an integer from {minimum} to {top}")
    return v


def real_array(a, name, dtype=np.float32):
    """``a`` as a real NumPy array of ``dtype``, without a copy when it already is one
    (strided views are kept as they are, the engine borrows them). Complex values are a
    ``TypeError`` (the imaginary part is never dropped silently); values that are not
    numbers a ``TypeError`` naming ``name``."""
    if isinstance(a, np.ndarray) and a.dtype == dtype:
        return a
    arr = np.asarray(a)
    if np.iscomplexobj(arr):
        raise TypeError(
            f"invalid parameter `{name}`: complex values ({arr.dtype}); radiance and images are "
            "real: pass `a.real` or `abs(a)` if that is what you mean"
        )
    if arr.dtype.kind not in "biuf":
        raise TypeError(f"invalid parameter `{name}`: an array of numbers, not dtype {arr.dtype}")
    return arr.astype(dtype, copy=False)


def float_list(v, name):
    """A list of Python floats from any 1-D sequence of real numbers."""
    arr = np.asarray(v)
    if np.iscomplexobj(arr):
        raise TypeError(f"invalid parameter `{name}`: complex values; real numbers expected")
    try:
        return [float(x) for x in arr.astype(np.float64).ravel()]
    except (TypeError, ValueError) as e:
        raise TypeError(f"invalid parameter `{name}` = {v!r}: numbers ({e})") from None


def real(name, v, optional=True):
    """A Python float (None passes when ``optional``)."""
    if v is None and optional:
        return None
    if isinstance(v, (complex, np.complexfloating)):
        raise TypeError(f"invalid parameter `{name}` = {v!r}: a real number")
    if isinstance(v, (bool, np.bool_)):
        raise TypeError(f"invalid parameter `{name}` = {v!r}: a number")
    try:
        return float(v)
    except (TypeError, ValueError):
        raise TypeError(f"invalid parameter `{name}` = {v!r}: a number") from None


def pair(name, v, what):
    """Two floats ``(a, b)``."""
    try:
        a, b = v
    except (TypeError, ValueError):
        raise ValueError(f"invalid parameter `{name}` = {v!r}: {what}") from None
    return (real(name, a, optional=False), real(name, b, optional=False))


def native(call, *args, **kwargs):
    """Calls the extension, turning the ``OverflowError`` an argument conversion raises
    (an integer beyond 64 bits) into the ``ValueError`` of the contract."""
    try:
        return call(*args, **kwargs)
    except OverflowError as e:
        raise ValueError(f"invalid parameter: {e} (an integer out of range)") from None
