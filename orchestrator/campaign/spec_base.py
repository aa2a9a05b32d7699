"""What every parser of the campaign file shares: its error and the key check."""

from __future__ import annotations

from ..scenario import check_keys

__all__ = ["CampaignError", "ENGINES", "check_table_keys"]

#: Campaign engines: the co-simulation master (the reference) and the linear fast path.
ENGINES = ("cosim", "linear")


class CampaignError(ValueError):
    """A campaign definition that is malformed or inconsistent."""


def check_table_keys(table, allowed, what: str) -> None:
    """Refuse a key of ``table`` that is not in ``allowed``, in one sentence naming
    ``what`` and the closest allowed key (:class:`CampaignError`).

    Parameters
    ----------
    table : dict
        The table read from the campaign file.
    allowed : sequence of str
        Its valid keys.
    what : str
        How the sentence names the table (``"[uncertainty]"``).
    """
    check_keys(table, allowed, what, CampaignError)
