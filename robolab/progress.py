"""Progress bars that leave a useful line in a saved notebook, not a frozen "0%".

In a live Jupyter kernel :func:`progress_bar` draws tqdm's widget bar; a widget's state is
not part of the notebook's saved outputs, so a notebook run headless (nbconvert, nbval,
CI) or opened in a viewer would keep only the bar's text as it was when drawn: "0%".
Here the bar is shown through a display handle, and when the loop ends the handle is
updated to tqdm's final text line (``scans: 100%|...| 400/400 [00:03, 120 scan/s]``), so
live and saved notebooks end on the same summary (or on nothing, with ``leave=False``).
Outside a kernel it is tqdm's text bar on stderr.
"""

from __future__ import annotations

from collections.abc import Iterable

__all__ = ["progress_bar", "in_kernel"]


def in_kernel() -> bool:
    """True inside an IPython kernel (Jupyter) with ipywidgets importable."""
    try:
        import ipywidgets  # noqa: F401
        from IPython import get_ipython
    except ImportError:
        return False
    shell = get_ipython()
    return shell is not None and getattr(shell, "kernel", None) is not None


def progress_bar(iterable: Iterable | None = None, desc: str | None = None, **kwargs):
    """``tqdm(iterable, desc, **kwargs)``, drawn as a widget in a kernel, as text elsewhere.

    Takes tqdm's arguments (``total``, ``unit``, ``leave``, ``disable``, ...) and is used
    like tqdm: iterate over it, or use it as a context manager and call ``update``.
    """
    if kwargs.get("disable") or not in_kernel():
        from tqdm.std import tqdm

        return tqdm(iterable, desc, **kwargs)
    return _notebook_bar()(iterable, desc, **kwargs)


def _notebook_bar():
    """The widget bar class (built on first use: importing tqdm.notebook needs ipywidgets)."""
    global _NotebookBar
    if _NotebookBar is not None:
        return _NotebookBar
    from IPython.display import display
    from tqdm.notebook import tqdm as tqdm_notebook

    class NotebookBar(tqdm_notebook):
        def __init__(self, *args, **kwargs):
            kwargs["display"] = False  # displayed here, through a handle that can be updated
            super().__init__(*args, **kwargs)
            self._handle = display(self.container, display_id=True)

        def close(self):
            if self.disable:
                return super().close()
            line = self.format_meter(**self.format_dict)
            leave = self.leave
            super().close()
            if self._handle is not None:
                self._handle.update({"text/plain": line if leave else ""}, raw=True)
                self._handle = None

    _NotebookBar = NotebookBar
    return NotebookBar


_NotebookBar = None
