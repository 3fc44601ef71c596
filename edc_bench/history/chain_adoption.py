"""On a station whose history is a chain's PostgreSQL, the model it judges with is the chain's word.

A station is *chain-connected* when its configured history (``EDC_BENCH_HISTORY_URL``) is PostgreSQL. There an
adoption (``train --adopt``) is recorded in that database, by an engineer's login (the database refuses any other),
under the station name the chain knows the station by (the owner's mapping of the station's login). An adoption
recorded anywhere else (``--db sqlite:///any.sqlite``) would change what the station judges with without the chain
hearing of it: it is refused (:func:`check_adoption_target`). Before each test the station's model is held to the
chain's newest adoption for it (:func:`chain_model_problem`).
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any

from edc_bench.errors import ConfigError
from edc_bench.timefmt import local_text

if TYPE_CHECKING:
    from edc_bench.history.store import HistoryStore


def chain_url() -> str | None:
    """The chain's history this station is connected to (``EDC_BENCH_HISTORY_URL``, when PostgreSQL), or None."""
    url = os.environ.get("EDC_BENCH_HISTORY_URL")
    return url if url and url.startswith("postgresql") else None


def _place(url: str) -> tuple[Any, ...]:
    """Which database a URL names (server, port, database, service), whoever logs in."""
    import sqlalchemy as sa

    parsed = sa.engine.make_url(url)
    return (parsed.get_backend_name(), parsed.host or "", parsed.port or 5432, parsed.database or "",
            parsed.query.get("service", ""), parsed.query.get("host", ""))


def check_adoption_target(db: str | None) -> None:
    """Refuse an adoption recorded in another history than the chain's this station is connected to.

    Raises
    ------
    ConfigError
        One line: whose login adopts, and where.
    """
    chain = chain_url()
    if chain is None or db is None:
        return
    from edc_bench.history.secrets import shown_url

    try:
        same = _place(db) == _place(chain)
    except Exception:  # noqa: BLE001 - a URL SQLAlchemy cannot read is not the chain's
        same = False
    if not same:
        raise ConfigError(f"this station's history is the chain's ({shown_url(chain)}, EDC_BENCH_HISTORY_URL): the "
                          "model it judges with is adopted there, by an engineer's login (a member of edc_engineer) "
                          f"on that database; --db {shown_url(db)} is another history, and nothing was adopted")


def chain_station(store: HistoryStore, fallback: str) -> str:
    """The name the chain knows this station by: the station the database login is mapped to (the login the
    store is connected as, else the station's own in ``EDC_BENCH_HISTORY_URL``), else ``fallback``."""
    if store.is_sqlite:
        return fallback
    if store.station:  # this connection's own login (a service-file URL names no user)
        return str(store.station)
    import sqlalchemy as sa

    from edc_bench.history.schema import edc_logins

    chain = chain_url()
    login = sa.engine.make_url(chain).username if chain else None
    if not login:
        return fallback
    with store.reading() as conn:
        mapped = conn.execute(sa.select(edc_logins.c.station).where(edc_logins.c.login == login)
                              .order_by(edc_logins.c.id.desc()).limit(1)).scalar()
    return str(mapped) if mapped else fallback


def allowed_models(store: HistoryStore, station: str, before: str | None = None) -> set[str]:
    """The SHA-256 of every model the station may judge with: the shipped ones, and each the history records an
    adoption of for ``station`` (up to ``before``, an ISO time, if given)."""
    import sqlalchemy as sa

    from edc_bench.history.schema import adoptions
    from edc_bench.verdict.classifier import shipped_model_hashes

    query = sa.select(adoptions.c.model_sha256).where(adoptions.c.station == station)
    if before is not None:
        query = query.where(adoptions.c.adopted_at <= before)
    with store.reading() as conn:
        return shipped_model_hashes() | {str(sha) for sha in conn.execute(query).scalars()}


def chain_model_problem(store: HistoryStore, station: str, model_sha256: str) -> str | None:
    """Why this station may not judge with the model whose SHA-256 is ``model_sha256`` (None: it is the one the
    chain's newest adoption for ``station`` names, or, with none, a shipped one)."""
    import sqlalchemy as sa

    from edc_bench.history.rows import AdoptionRow
    from edc_bench.history.schema import adoptions

    with store.reading() as conn:
        newest = [AdoptionRow.of(r._mapping) for r in conn.execute(
            sa.select(adoptions).where(adoptions.c.station == station).order_by(adoptions.c.id.desc()).limit(1))]
    fix = ("an engineer adopts it here with 'edc-bench train --adopt FILE' (the chain's history in "
           "EDC_BENCH_HISTORY_URL), or test with --no-history")
    if not newest:
        from edc_bench.verdict.classifier import file_sha256, packaged_model_path

        if model_sha256 == file_sha256(packaged_model_path()):  # the shipped default: what a new station judges with
            return None
        return (f"this station judges with a model (sha256 {model_sha256[:12]}...) the chain records no adoption of "
                f"for station {station!r}: it judges with the shipped models until one is adopted there; "
                "'edc-bench train --adopt shipped' goes back to them, or " + fix)
    row = newest[0]
    if row.model_sha256 == model_sha256:
        return None
    return (f"this station judges with a model (sha256 {model_sha256[:12]}...) that is not the one the chain records "
            f"for station {station!r}: {row.model_name} (sha256 {row.model_sha256[:12]}..., adopted by "
            f"{row.adopted_by} at {local_text(row.adopted_at)}); {fix}")


__all__ = ["allowed_models", "chain_model_problem", "chain_station", "chain_url", "check_adoption_target"]
