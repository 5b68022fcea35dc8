"""The file magics of a notebook run for grading: ``%%writefile`` and ``%run``, inside one folder.

In Jupyter a notebook's working folder is its own folder: ``%%writefile helper.py``
writes there, ``import helper`` finds it (the folder is on ``sys.path``) and
``%run helper.py`` runs it. Graded, the notebook's working folder is the
worker's scratch folder (the only place the sandbox lets it write), so both
magics work there, and only there: a path that leaves the folder (``..``,
an absolute path, a symbolic link out) is refused before anything is opened.
``%run`` of such a path says what IPython says for a file that does not exist,
so a student reads the same thing as in a fresh Jupyter kernel given only the
notebook, and nothing outside the folder is read (docs/grading.md section 1).

The behaviour follows IPython 8-9 (``IPython.core.magics.osm.writefile``,
``IPython.core.magics.execution.run``): ``%%writefile [-a] FILE`` prints
"Writing"/"Overwriting"/"Appending to" and writes the cell as UTF-8;
``%run [-i] [-n] [-e] FILE [ARGS]`` runs the file as ``__main__`` with
``sys.argv = [FILE, *ARGS]`` in a fresh namespace whose names are then copied
into the notebook's (with ``-i``: in the notebook's namespace itself); an
exception in the file is printed and the cell goes on, as IPython's
``safe_execfile`` does. ``.ipy`` and ``.ipynb`` files run their IPython
source in the notebook's namespace.
"""

from __future__ import annotations

import getopt
import json
import os
import shlex
import sys
import traceback
import types

__all__ = ["FolderError", "inside", "run_file", "write_file"]

#: Options of ``%run`` as IPython parses them (getopt syntax).
RUN_OPTIONS = "nidtN:b:pD:l:rs:T:em:G"


class FolderError(PermissionError):
    """A file magic named a path outside the notebook's working folder."""


def inside(folder: str, name: str) -> str | None:
    """The real path of ``name`` (relative to ``folder``) if it stays inside ``folder``, else None.

    Symbolic links are resolved first, so a link pointing out of the folder is outside too.
    """
    root = os.path.realpath(folder)
    path = os.path.realpath(os.path.join(root, os.path.expanduser(name)))
    return path if path == root or path.startswith(root.rstrip(os.sep) + os.sep) else None


def write_file(folder: str, line: str, body: str) -> None:
    """``%%writefile [-a|--append] FILE``: write (or append) the cell body to FILE in ``folder``.

    Raises
    ------
    FolderError
        When FILE is outside ``folder`` (nothing is written).
    ValueError
        When the line names no file.
    """
    words = shlex.split(line)
    append = any(w in ("-a", "--append") for w in words)
    names = [w for w in words if w not in ("-a", "--append")]
    if len(names) != 1:
        raise ValueError(f"%%writefile needs exactly one file name, got {line!r}")
    name = names[0]
    target = inside(folder, name)
    if target is None:
        raise FolderError(
            f"%%writefile {name}: when graded, a notebook writes files only in its own "
            "working folder (write a relative path such as helper.py)"
        )
    if os.path.exists(target):
        print(f"{'Appending to' if append else 'Overwriting'} {name}")
    else:
        print(f"Writing {name}")
    with open(target, "a" if append else "w", encoding="utf-8") as f:
        f.write(body)


def _not_found(name: str) -> Exception:
    # IPython's own words (get_py_filename), so a student reads what a fresh kernel says.
    return Exception(
        f"File `{name!r}` not found. (When graded, only files your notebook writes itself, "
        "for example with %%writefile, are in its folder.)"
    )


def _find(folder: str, name: str) -> str:
    """IPython's ``get_py_filename`` within ``folder``: NAME, else NAME.py; refused outside it."""
    for candidate in (name, name + ".py") if not name.endswith(".py") else (name,):
        path = inside(folder, candidate)
        if path is not None and os.path.isfile(path):
            return path
    raise _not_found(os.path.expanduser(name))


def run_file(folder: str, line: str, user_ns: dict, run_ipython) -> None:
    """``%run [options] FILE [ARGS]`` as IPython runs it, for files inside ``folder`` only.

    Parameters
    ----------
    folder : str
        The notebook's working folder.
    line : str
        The magic's argument line.
    user_ns : dict
        The notebook's namespace.
    run_ipython : callable
        ``run_ipython(sources, filename)`` runs IPython cell sources (a ``.ipy``
        file, or a notebook's code cells) in the notebook's namespace.
    """
    try:
        opts, args = getopt.getopt(shlex.split(line), RUN_OPTIONS)
    except (getopt.GetoptError, ValueError) as exc:
        raise Exception(f"%run {line}: {exc}") from None
    flags = {flag.lstrip("-") for flag, _ in opts}
    if "m" in flags:
        module = dict(opts)["-m"]
        path = inside(folder, module.replace(".", os.sep) + ".py")
        if path is None or not os.path.isfile(path):
            raise Exception(f"{module!r} is not a valid modulename on sys.path")
        args = [path, *args]
    if not args:
        raise Exception("you must provide at least a filename.")
    filename = _find(folder, args[0])
    if filename.lower().endswith((".ipy", ".ipynb")):
        sources = _ipython_sources(filename)
        saved = user_ns.get("__file__", _MISSING)
        user_ns["__file__"] = filename
        try:
            run_ipython(sources, filename)
        finally:
            _restore(user_ns, "__file__", saved)
        return
    name = os.path.splitext(os.path.basename(filename))[0] if "n" in flags else "__main__"
    if "i" in flags:
        namespace = user_ns
        saved_name = user_ns.get("__name__", _MISSING)
    else:
        module = types.ModuleType(name)
        namespace = module.__dict__
        namespace["__builtins__"] = user_ns.get("__builtins__", __builtins__)
    namespace["__name__"] = name
    namespace["__file__"] = filename
    saved_argv, saved_main = sys.argv, sys.modules.get(name, _MISSING)
    sys.argv = [filename, *args[1:]]
    if "i" not in flags:
        sys.modules[name] = module
    try:
        _execfile(filename, namespace, exit_ignore="e" in flags)
        if "i" in flags:
            _restore(user_ns, "__name__", saved_name)
        else:
            namespace.pop("__name__", None)
            saved_file = user_ns.get("__file__", _MISSING)
            user_ns.update(namespace)
            _restore(user_ns, "__file__", saved_file)
    finally:
        user_ns["__builtins__"] = namespace.get("__builtins__", user_ns.get("__builtins__"))
        sys.argv = saved_argv
        _restore(sys.modules, name, saved_main)


_MISSING = object()


def _restore(mapping: dict, key: str, value: object) -> None:
    if value is _MISSING:
        mapping.pop(key, None)
    else:
        mapping[key] = value


def _execfile(filename: str, namespace: dict, *, exit_ignore: bool) -> None:
    """IPython's ``safe_execfile``: an exception is printed, not raised; ``exit(0)`` is silent."""
    try:
        with open(filename, encoding="utf-8") as f:
            code = compile(f.read(), filename, "exec", dont_inherit=True)
        exec(code, namespace)  # noqa: S102 - the student's own file, in the student's sandbox
    except SystemExit as exc:
        if exc.code not in (0, None) and not exit_ignore:
            traceback.print_exc()
    except Exception:  # noqa: BLE001 - IPython shows the traceback and the cell goes on
        traceback.print_exc()


def _ipython_sources(filename: str) -> list[str]:
    """The cells of a ``.ipy`` file (one) or of a notebook (its code cells)."""
    with open(filename, encoding="utf-8") as f:
        text = f.read()
    if not filename.lower().endswith(".ipynb"):
        return [text]
    try:
        cells = json.loads(text).get("cells", [])
    except (ValueError, AttributeError) as exc:
        raise Exception(f"{os.path.basename(filename)} is not a notebook: {exc}") from None
    parts = []
    for cell in cells:
        if isinstance(cell, dict) and cell.get("cell_type") == "code":
            source = cell.get("source", "")
            parts.append("".join(source) if isinstance(source, list) else str(source))
    return parts
