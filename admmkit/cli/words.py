"""The words of the command line: the closest name for a misspelt one, and help text without markup."""
from __future__ import annotations

import difflib
import re


def did_you_mean(word: str, candidates) -> str:
    """`` (did you mean X?)`` for the candidate closest to a misspelt ``word`` (difflib), else ``""``."""
    close = difflib.get_close_matches(str(word), [str(c) for c in candidates], n=1, cutoff=0.6)
    return f" (did you mean {close[0]}?)" if close else ""


def plain(text: str | None) -> str | None:
    """Help text without reStructuredText or Markdown markup: double or single backquotes, double or single
    stars and a role before backquotes (``:mod:`` and the like) are dropped, the text between them kept."""
    if not text:
        return text
    text = re.sub(r":[a-z]+:`~?([^`]+)`", r"\1", text)          # :mod:`admmkit.cli` -> admmkit.cli
    text = re.sub(r"`{1,2}([^`]+)`{1,2}", r"\1", text)           # ``x`` and `x` -> x
    text = re.sub(r"\*\*([^*]+)\*\*", r"\1", text)                   # **x** -> x
    return re.sub(r"(?<![\w*])\*([^*\s][^*]*?)\*(?![\w*])", r"\1", text)  # *x* -> x, but not a*b*c
