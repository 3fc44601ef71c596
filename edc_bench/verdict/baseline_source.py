"""Where the tests behind a baseline ran: a value the verdict decides on, never a sentence it parses."""

from __future__ import annotations

from enum import StrEnum


class BaselineSource(StrEnum):
    """Where a baseline's test ran (its value is the word a baseline file and a record hold)."""

    RIG = "rig"
    SIMULATED_RIG = "simulated rig"
    SIMULATED_POPULATION = "simulated population"
    #: no test: the variant's nominal physics (an uncalibrated variant)
    NOMINAL = "nominal physics (uncalibrated)"
    #: a file's word edc-bench does not know (never taken for a rig)
    UNKNOWN = "unknown"

    @classmethod
    def parse(cls, word: str) -> BaselineSource:
        """The source a file or record names (:attr:`UNKNOWN` for a word edc-bench does not know)."""
        try:
            return cls(word.strip())
        except ValueError:
            return cls.UNKNOWN


def sources_of_text(text: str) -> frozenset[BaselineSource]:
    """The sources an older baseline or record names only in its sentence (``"rig and simulated rig"``): the one
    place that reads that wording, for files and records written before the sources were kept as values."""
    words = [part for part in text.split(" and ") if part.strip()]
    return frozenset(BaselineSource.parse(word) for word in words) or frozenset({BaselineSource.UNKNOWN})


def sources_text(sources: frozenset[BaselineSource]) -> str:
    """The sources in one line, for people and for a baseline file's ``source`` (sorted, joined by 'and')."""
    return " and ".join(sorted(str(source) for source in sources)) or str(BaselineSource.UNKNOWN)
