"""What every parser of the campaign file shares: its error and the key check."""

from __future__ import annotations

from ..scenario import check_keys

__all__ = ["CampaignError", "ENGINES"]

#: Campaign engines: the co-simulation master (the reference) and the linear fast path.
ENGINES = ("cosim", "linear")


class CampaignError(ValueError):
    """A campaign definition that is malformed or inconsistent."""


def _check_keys(table, allowed, what: str) -> None:
    check_keys(table, allowed, what, CampaignError)
