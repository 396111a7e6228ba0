"""The one exception type for bad input.

Library code raises :class:`UserError` for anything the user can fix (a bad file, an
out-of-range argument, an unknown part name). The CLI turns it into one ``error: ...``
line on stderr and exit status 2.
"""


class UserError(Exception):
    """Bad input the user can fix; the message is shown as-is after ``error:``."""


def close_matches(word: str, candidates, n: int = 3) -> str:
    """A short 'did you mean' suffix listing the closest candidates (or all, if few)."""
    import difflib

    candidates = sorted(set(candidates))
    matches = difflib.get_close_matches(word, candidates, n=n, cutoff=0.4)
    if not matches:
        matches = candidates[:n]
    return ", ".join(matches)
