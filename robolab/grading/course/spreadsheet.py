"""CSV that a spreadsheet opens as data: no cell it would evaluate as a formula.

Every CSV robolab writes (the gradebook, the Canvas and Moodle exports) holds text
that students control, directly (roster names and ids pass through instructors, but
come from students) or through files (submission file names, a notebook's metadata,
error and feedback text). A spreadsheet evaluates a cell whose first character is
``=``, ``+``, ``-`` or ``@`` as a formula (``=HYPERLINK(...)`` exfiltrates,
``=cmd|' /C calc'!A0`` runs a program through DDE), and tab, carriage return and
line feed lead to the same on some (OWASP, "CSV Injection"). Following that
guidance, :func:`safe_cell` prefixes such a cell with a single quote, which makes
every spreadsheet read it as text, and :func:`csv_text` writes RFC 4180 CSV (a cell
holding a separator, a quote or a line break is quoted, quotes doubled), so that no
dangerous character can start a cell of its own.

A cell that is a plain decimal number (``-2.5``, ``+3``, ``1e-3``) is left as it is:
a spreadsheet reads it as that number, never as a formula, and LMS imports need
scores (even negative ones) to stay numbers.
"""

from __future__ import annotations

import csv
import io
import numbers
import re
from collections.abc import Iterable

__all__ = ["FORMULA_TRIGGERS", "csv_text", "safe_cell"]

#: First characters that make a spreadsheet evaluate a cell (OWASP's list).
FORMULA_TRIGGERS = frozenset("=+-@\t\r\n")
_NUMBER = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")


def safe_cell(value: object) -> str:
    """``value`` as the text of a CSV cell that no spreadsheet evaluates.

    Parameters
    ----------
    value : object
        None (an empty cell), a number (written as is), or anything else (its ``str``).

    Returns
    -------
    str
        The text, with a single quote in front when it (or its text after leading
        white space, which some spreadsheets trim) starts with ``= + - @``, a tab,
        a carriage return or a line feed, unless it is a plain decimal number.
    """
    if value is None:
        return ""
    text = str(value)
    if isinstance(value, numbers.Number) and not isinstance(value, bool):
        return text  # a number: "-3" is minus three, never a formula
    first = text[:1]
    if (first in FORMULA_TRIGGERS or text.lstrip()[:1] in FORMULA_TRIGGERS) and first:
        if not _NUMBER.fullmatch(text):
            return "'" + text
    return text


def csv_text(rows: Iterable[Iterable[object]]) -> str:
    """RFC 4180 CSV text of ``rows``, every cell through :func:`safe_cell`.

    Use it for every CSV written for people or LMS imports; the header row too.
    """
    buffer = io.StringIO()
    writer = csv.writer(buffer)
    for row in rows:
        writer.writerow([safe_cell(cell) for cell in row])
    return buffer.getvalue()
