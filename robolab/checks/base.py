"""Shared machinery for visible checks: one way to report success and failure."""

from __future__ import annotations

import functools

import numpy as np


class CheckFailed(AssertionError):
    """A visible check found a problem; the message says what and how to look into it."""


def passed(name: str, detail: str = "") -> None:
    """Print the friendly success line for check ``name``."""
    print(f"\u2714 {name}: ok" + (f" ({detail})" if detail else ""))


def check(func):
    """Decorate a visible check: NotImplementedError and other errors become a CheckFailed."""

    @functools.wraps(func)
    def wrapper(student_function, *args, **kwargs):
        name = getattr(student_function, "__name__", "function")
        try:
            result = func(student_function, *args, **kwargs)
        except NotImplementedError:
            raise CheckFailed(
                f"{name} is not implemented yet: replace `raise NotImplementedError` with your code"
            ) from None
        except CheckFailed:
            raise
        except Exception as exc:  # the student's code raised: show it plainly
            raise CheckFailed(f"{name} raised {type(exc).__name__}: {exc}") from exc
        passed(name)
        return result

    return wrapper


def expect_close(what: str, got, expected, *, atol: float = 1e-8, rtol: float = 1e-6) -> None:
    """Raise CheckFailed unless ``got`` equals ``expected`` within tolerance, as float arrays."""
    try:
        g = np.asarray(got, dtype=float)
    except (TypeError, ValueError):
        raise CheckFailed(f"{what}: expected numbers, got {type(got).__name__}") from None
    e = np.asarray(expected, dtype=float)
    if g.shape != e.shape:
        raise CheckFailed(f"{what}: expected shape {e.shape}, got {g.shape}")
    if not np.allclose(g, e, atol=atol, rtol=rtol, equal_nan=False):
        raise CheckFailed(
            f"{what}: expected {np.array2string(e, precision=4)}, "
            f"got {np.array2string(g, precision=4)}"
        )


def expect_shape(what: str, got, shape) -> np.ndarray:
    """Raise CheckFailed unless ``got`` is an array of ``shape``; return it as a float array."""
    g = np.asarray(got, dtype=float)
    if g.shape != tuple(shape):
        raise CheckFailed(f"{what}: expected shape {tuple(shape)}, got {g.shape}")
    return g


def expect_raises(what: str, error: type[BaseException], func, *args, **kwargs) -> None:
    """Raise CheckFailed unless ``func(*args, **kwargs)`` raises ``error`` (bad input refused).

    NotImplementedError is let through, so the check says "not implemented yet".
    """
    try:
        func(*args, **kwargs)
    except NotImplementedError:
        raise
    except error:
        return
    except Exception as exc:  # noqa: BLE001 - any other error is the wrong kind of refusal
        raise CheckFailed(
            f"{what}: expected {error.__name__}, got {type(exc).__name__}: {exc}"
        ) from None
    raise CheckFailed(f"{what}: expected {error.__name__}, but the function returned normally")


def where_wrong(z, got, expected, marks: dict, normaliser: str) -> str | None:
    """None when ``got`` matches ``expected`` at every reading ``z``; else where it differs.

    A density wrong only at single readings (``marks``: label -> reading, such as
    the ends of its support and z*) is named there; one off by the same factor at
    every reading has a wrong normaliser (``normaliser`` says which); anything else
    is shown at its first wrong readings.
    """
    bad = ~np.isclose(got, expected, rtol=1e-9, atol=1e-300)
    if not bad.any():
        return None

    def at(i):
        return f"at z = {z[i]:.6g} got {got[i]:.6g}, expected {expected[i]:.6g}"

    wrong = np.flatnonzero(bad)
    labels = {i: [k for k, v in marks.items() if z[i] == v] for i in wrong}
    if all(labels.values()):
        where = "; ".join(f"{' = '.join(labels[i])}: {at(i)}" for i in wrong)
        return (
            f"wrong only at single readings ({where}), right everywhere else: look at how the "
            "support's ends are included (<= or <), not at the normaliser"
        )
    positive = expected > 1e-300
    ratio = got[positive] / expected[positive]
    if positive.any() and bad[positive].all() and np.ptp(ratio) <= 1e-9 * abs(ratio[0]):
        return f"off by the same factor {ratio[0]:.6g} at every reading: {normaliser}"
    shown = "; ".join(at(i) for i in wrong[:3])
    return f"wrong at {wrong.size} of {z.size} readings, e.g. {shown}"


def angle_error(got, expected, atol: float) -> str | None:
    """None when the angles ``got`` and ``expected`` agree modulo 2 pi within ``atol``.

    Otherwise a sentence naming the largest error (not the angle) and where it is,
    with the angle got and the angle expected there: printing the error as the
    result would make a student read their error as what their function returned.
    """
    g = np.asarray(got, dtype=float)
    e = np.broadcast_to(np.asarray(expected, dtype=float), g.shape)
    err = np.abs((g - e + np.pi) % (2 * np.pi) - np.pi)
    err = np.where(np.isnan(err), np.inf, err)
    if err.size == 0 or err.max() <= atol:
        return None
    i = np.unravel_index(int(np.argmax(err)), err.shape)
    where = f" at index {i[0] if len(i) == 1 else tuple(int(k) for k in i)}" if i else ""
    size = f"reaches {err[i]:.3g} rad" if np.isfinite(err[i]) else "is not a number"
    return (
        f"the angle error {size}{where} (tolerance {atol:g}): got "
        f"{g[i]:.6g} rad, expected {e[i]:.6g} rad (modulo 2 pi)"
    )
