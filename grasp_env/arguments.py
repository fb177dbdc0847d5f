"""Checks of the numbers users pass in (actions, hand targets, reset options, scene
fields): errors name the argument and show the value.

A real number is an int or a float, as a Python or numpy scalar or an int or float array;
strings, complex numbers, bools, None and object arrays are refused rather than parsed or
cast (a complex number would lose its imaginary part, a bool would act as 0 or 1).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

#: Real numbers as Python or numpy scalars, and as an array's ``dtype.kind``.
REAL_TYPES = (int, float, np.integer, np.floating)
REAL_KINDS = "iuf"


def short(value: Any) -> str:
    """``repr`` of a value for an error message: on one line, at most 80 characters."""
    text = " ".join(repr(value).split())
    return text if len(text) <= 80 else text[:77] + "..."


def is_real(value: Any) -> bool:
    """Whether a scalar is a real number (an int or a float, not a bool)."""
    return isinstance(value, REAL_TYPES) and not isinstance(value, bool)


def unmasked(value: Any, what: str) -> Any:
    """``value``, or the data of a masked array with nothing masked; ``ValueError``
    (``what``, then the masked value) where entries are masked: a masked entry has no
    value to act on."""
    if isinstance(value, np.ma.MaskedArray):
        if np.ma.is_masked(value):
            raise ValueError(f"{what}, got masked entries: {short(value)}")
        return value.data
    return value


def real_vector(value: Any, name: str, size: int) -> np.ndarray:
    """``value`` as a new array of ``size`` finite floats, or ``ValueError`` naming ``name``
    and showing the value (:func:`real_array`)."""
    return real_array(value, name, (size,), f"{size} real numbers")


def real_array(value: Any, name: str, shape: tuple[int, ...], what: str = "") -> np.ndarray:
    """``value`` as a new float array of ``shape``, finite, or
    ``ValueError`` naming ``name`` and showing the value: nested sequences of real numbers
    or an int or float array (a masked one only with nothing masked). ``what`` says what
    is expected (default: real numbers of ``shape``)."""

    def expected() -> str:  # built only for an error: a step's check of its actions is hot
        return f"{name} must be {what or f'real numbers of shape {shape}'}"

    if isinstance(value, np.ma.MaskedArray):
        value = unmasked(value, expected())
    is_array = isinstance(value, np.ndarray)
    try:
        arr = value if is_array else np.asarray(value, dtype=object)
    except (TypeError, ValueError):  # nesting numpy cannot even hold as objects
        raise ValueError(f"{expected()}, got {short(value)}") from None
    if arr.shape != shape:
        raise ValueError(f"{expected()}, got {short(value)} of shape {arr.shape}")
    if not (arr.dtype.kind in REAL_KINDS if is_array else all(map(is_real, arr.flat))):
        raise ValueError(
            f"{name} must be real numbers (int or float; not bool, str, complex or object), "
            f"got {short(value)}"
        )
    if is_array and arr.dtype.itemsize <= 8:
        arr = arr.astype(float)  # no wider than a float: nothing overflows
    else:
        try:
            with np.errstate(over="ignore"):  # a long double beyond the float range
                arr = arr.astype(float)
        except OverflowError:  # a Python int beyond the float range
            arr = np.full(shape, math.inf)
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} must be finite, got {short(value)}")
    return arr


def number(
    value: Any,
    name: str,
    lo: float,
    hi: float,
    lo_open: bool = True,
    hi_open: bool = False,
) -> float:
    """A real number (not a bool) as a float, finite and within ``lo`` and ``hi`` (each
    bound open or closed): ``TypeError`` for a non-number, else ``ValueError``."""
    if not is_real(value):
        raise TypeError(f"{name} must be a number, got {short(value)}")
    try:
        x = float(value)
    except OverflowError:  # an int beyond the float range
        x = math.inf
    ok = math.isfinite(x) and (x > lo if lo_open else x >= lo) and (x < hi if hi_open else x <= hi)
    if not ok:
        interval = f"{'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"
        raise ValueError(f"{name} must be finite and in {interval}, got {short(value)}")
    return x


def integer(
    value: Any, name: str, least: int, wrong_type: type = ValueError, most: int | None = None
) -> int:
    """An int (not a bool) in ``[least, most]`` (``most`` None: no upper bound);
    ``wrong_type`` for a non-integer, else ``ValueError``."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise wrong_type(f"{name} must be an integer >= {least}, got {value!r}")
    if value < least or (most is not None and value > most):
        bounds = f">= {least}" if most is None else f"in [{least}, {most}]"
        raise ValueError(f"{name} must be an integer {bounds}, got {value!r}")
    return int(value)
