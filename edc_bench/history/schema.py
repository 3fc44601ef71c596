"""The history's tables, as the newest migration leaves them (:mod:`edc_bench.history.migrations`).

Every table is append-only: a row, once stored, is never updated or deleted
(the database refuses it: triggers on SQLite and PostgreSQL, and on
PostgreSQL the roles' privileges, :mod:`edc_bench.history.roles`). What
changes is said by a new row naming the row it concerns:

- ``tests``: one row per test (``test_key``: the id record.json carries) and
  content; its first row is the test as it stands (its *anchor*). Indexing it
  again with other content adds a row that every reader shows as a change;
  copies of its folder are the same test. Each row keeps the SHA-256 of
  record.json as it was read and the record's own integrity manifest, for
  ``history --verify``.
- ``teardowns``: what a valve's teardown found; ``corrects_id`` names a finding
  this one replaces.
- ``amendments``: a withdrawal of a test or of a finding, with who, when and why.
- ``adoptions``: a model a station was given to judge with, who adopted it and when.
- ``reference_valves``: a station's reference valve for the rig self-check and its figures when registered; a
  registration again is a new row, and the station's newest stands.
- ``rig_checks``: each rig self-check (``edc-bench rig-selfcheck``): GO or NO-GO, the drifts named, its
  figures, and the registration it was compared with (the ledger, ``history --rig``); and each due check the
  technician skipped (SKIPPED, no figures).

Every row is hash-chained (``prev_hash``, ``row_hash``: :mod:`edc_bench.history.chain`).

Who: ``*_by`` is the person (``--by``, or the operating-system login), ``db_login`` the database login that
wrote the row (on PostgreSQL; None on SQLite, where the file's permissions say who may write).
"""

from __future__ import annotations

import sqlalchemy as sa

from edc_bench.history.rows import NOT_LISTED

metadata = sa.MetaData()


def _chain() -> list[sa.Column]:
    """Every row's place in its chain (:mod:`edc_bench.history.chain`): the hash of the chain's row before it,
    and its own."""
    return [sa.Column("prev_hash", sa.String(64)), sa.Column("row_hash", sa.String(64))]


tests = sa.Table(
    "tests", metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("record_dir", sa.String(1024), nullable=False, index=True),
    sa.Column("started_at", sa.String(40), nullable=False, index=True),
    sa.Column("valve_id", sa.String(200), nullable=False, index=True),
    sa.Column("pump_serial", sa.String(200), nullable=False, index=True),
    sa.Column("variant", sa.String(200), nullable=False),
    sa.Column("part_number", sa.String(100), nullable=False),
    sa.Column("verdict", sa.String(20), nullable=False),
    sa.Column("af_v", sa.Float),
    sa.Column("a1_v_s_per_mm", sa.Float),
    sa.Column("af_rel", sa.Float),
    sa.Column("a1_rel", sa.Float),
    sa.Column("probability_faulty", sa.Float),
    sa.Column("distance", sa.Float),
    sa.Column("station", sa.String(200), nullable=False),
    sa.Column("operator", sa.String(200), nullable=False),
    sa.Column("clock", sa.String(20), nullable=False),
    sa.Column("software_version", sa.String(40), nullable=False),
    sa.Column("reason", sa.Text, nullable=False),
    sa.Column("model_name", sa.String(200)),  # the classifier that judged (None: not classified)
    sa.Column("model_sha256", sa.String(64)),
    # how the test went: the coil (referred to 20 degC; in its spec?), whether the model fitted the pump, when and
    # why it stopped (None in rows of an older edc-bench, and where the record does not say)
    sa.Column("coil_r20_ohm", sa.Float),
    sa.Column("coil_in_spec", sa.Boolean),
    sa.Column("model_fits", sa.Boolean),
    sa.Column("stop_reason", sa.String(40)),
    sa.Column("test_s", sa.Float),
    sa.Column("simulated", sa.Boolean),  # on the simulated rig: out of trends and training unless asked for
    # a retest of a MARGINAL: the record folder of the test it repeats, and what the two decided (PASS, FAIL or
    # INVALID; None for a test that repeats none)
    sa.Column("retest_of", sa.String(1024)),
    sa.Column("decision", sa.String(20)),
    # the record as it was indexed (None in rows indexed before the history kept it)
    sa.Column("record_sha256", sa.String(64)),
    sa.Column("record_manifest", sa.Text),  # record.json's integrity section as JSON (records of schema 5 on)
    sa.Column("indexed_at", sa.String(40)),
    sa.Column("indexed_by", sa.String(200)),
    sa.Column("db_login", sa.String(200)),
    # the test's own id (record.json's test_id; a key from its when/valve/pump/station for older records)
    sa.Column("test_key", sa.String(200), index=True),
    # what the record says of when, which valve, which pump and where (chain.legacy_test_key), for every row: a
    # copy stripped of its id is still the same test
    sa.Column("legacy_key", sa.String(200), index=True),
    *_chain(),
    # where an INVALID test points the technician (edc_bench.records.advice.Area; None for other verdicts and in rows
    # indexed before revision 0007)
    sa.Column("invalid_area", sa.String(20)),
    # whether this row is its test's first indexing (False: the test indexed again with other content); None in rows
    # stored before revision 0008 (ask the earlier rows). PostgreSQL's trigger sets it; history --verify checks it
    sa.Column("first_indexing", sa.Boolean),
    # the part at fault (edc_bench.verdict.part_sections.Part); None in rows indexed before revision 0010, whose
    # records judged the valve alone
    sa.Column("part", sa.String(30)),
    # a station's tests by time: the chain's figures per station and day, and each station's latest test
    sa.Index("ix_tests_station_started_at", "station", "started_at"),
    # a technician's tests by time (revision 0008)
    sa.Index("ix_tests_operator_started_at", "operator", "started_at"),
    # a pump type's tests by time, whichever name the filter gives (revision 0009)
    sa.Index("ix_tests_variant_started_at", "variant", "started_at"),
    sa.Index("ix_tests_part_number_started_at", "part_number", "started_at"),
)

teardowns = sa.Table(
    "teardowns", metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("valve_id", sa.String(200), nullable=False, index=True),
    sa.Column("finding", sa.String(20), nullable=False),
    sa.Column("clearance_mm", sa.Float),
    sa.Column("note", sa.Text, nullable=False),
    sa.Column("labelled_by", sa.String(200), nullable=False),
    sa.Column("labelled_at", sa.String(40), nullable=False),  # ISO date or date-time (UTC) of the teardown
    sa.Column("recorded_at", sa.String(40), nullable=False),
    sa.Column("corrects_id", sa.Integer),  # the finding this one replaces
    sa.Column("db_login", sa.String(200)),
    sa.Column("recorded_by", sa.String(200)),  # who filed it (the login's person on PostgreSQL); labelled_by opened it
    *_chain(),
)

amendments = sa.Table(
    "amendments", metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("target", sa.String(20), nullable=False),  # 'tests' or 'teardowns'
    sa.Column("target_id", sa.Integer, nullable=False),
    sa.Column("action", sa.String(20), nullable=False),  # 'withdraw'
    sa.Column("reason", sa.Text, nullable=False),
    sa.Column("amended_by", sa.String(200), nullable=False),
    sa.Column("amended_at", sa.String(40), nullable=False),
    sa.Column("db_login", sa.String(200)),
    *_chain(),
)

adoptions = sa.Table(
    "adoptions", metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("station", sa.String(200), nullable=False),
    sa.Column("model_name", sa.String(200), nullable=False),
    sa.Column("model_sha256", sa.String(64), nullable=False),
    sa.Column("adopted_by", sa.String(200), nullable=False),
    sa.Column("adopted_at", sa.String(40), nullable=False),
    sa.Column("db_login", sa.String(200)),
    # what the adoption was decided on (revision 0009): a shop candidate's cross-validated figures beside the model
    # it replaced, as JSON (edc_bench.learning.shop_training.CandidateEvaluation); None for a model without them
    sa.Column("evaluation", sa.Text),
    *_chain(),
)

#: The figures of the reference valve and the rig at rest (:data:`edc_bench.selfcheck.compare.QUANTITIES`).
FIGURES = ("lvdt_zero_mm", "current_zero_a", "coil_r20_ohm", "a0_v_per_mm", "af_v", "a1_v_s_per_mm")


def _figures() -> list[sa.Column]:
    return [sa.Column(name, sa.Float) for name in FIGURES] + [sa.Column("lvdt_at_floor", sa.Boolean)]


reference_valves = sa.Table(
    "reference_valves", metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("station", sa.String(200), nullable=False, index=True),
    sa.Column("valve_id", sa.String(200), nullable=False),
    sa.Column("variant", sa.String(200), nullable=False),
    *_figures(),
    sa.Column("coil_temp_c", sa.Float),
    sa.Column("simulated", sa.Boolean, nullable=False),
    sa.Column("valve_spec", sa.String(200)),  # the simulated valve (None on a rig)
    sa.Column("details", sa.Text),  # JSON: how it was measured
    sa.Column("software_version", sa.String(40), nullable=False),
    sa.Column("registered_by", sa.String(200), nullable=False),
    sa.Column("registered_at", sa.String(40), nullable=False),
    sa.Column("db_login", sa.String(200)),
    *_chain(),
)

rig_checks = sa.Table(
    "rig_checks", metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("station", sa.String(200), nullable=False, index=True),
    sa.Column("reference_id", sa.Integer, nullable=False),  # the registration compared with
    sa.Column("verdict", sa.String(10), nullable=False),  # GO or NO-GO
    sa.Column("causes", sa.Text, nullable=False),  # the drifts named, comma-separated ('' for GO)
    sa.Column("words", sa.Text, nullable=False),  # the line the technician read
    *_figures(),
    sa.Column("coil_temp_c", sa.Float),
    sa.Column("simulated", sa.Boolean, nullable=False),
    sa.Column("details", sa.Text),  # JSON: every figure's drift and tolerance, how it was measured
    sa.Column("software_version", sa.String(40), nullable=False),
    sa.Column("checked_by", sa.String(200), nullable=False),
    sa.Column("checked_at", sa.String(40), nullable=False, index=True),
    sa.Column("db_login", sa.String(200)),
    *_chain(),
)

#: Which station (and person) each database login is: kept by the chain's owner (``history --map-login``); a
#: login's newest row stands. The database sets a row's station and person from it (PostgreSQL).
edc_logins = sa.Table(
    "edc_logins", metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("login", sa.String(200), nullable=False, index=True),
    sa.Column("station", sa.String(200)),  # None: a login that is no station's (an engineer's)
    sa.Column("person", sa.String(200)),
    sa.Column("shop", sa.String(200)),  # the shop the station belongs to (None: not said)
    sa.Column("mapped_by", sa.String(200), nullable=False),
    sa.Column("mapped_at", sa.String(40), nullable=False),
)

#: The rows written before the chain began (revision 0006), one digest per table and chain
#: (:func:`edc_bench.history.chain.anchor_hash`): the first chained row of the chain follows it.
chain_anchors = sa.Table(
    "chain_anchors", metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("tbl", sa.String(40), nullable=False),
    sa.Column("chain", sa.String(200), nullable=False),
    sa.Column("rows", sa.Integer, nullable=False),
    sa.Column("last_id", sa.Integer, nullable=False),
    sa.Column("hash", sa.String(64), nullable=False),
    sa.Column("made_at", sa.String(40), nullable=False),
)

#: What the history's guard found and did: a station's SQLite triggers found missing or changed, and restored
#: (kept, chained: ``history --verify`` names it every time after).
guard_events = sa.Table(
    "guard_events", metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("event", sa.String(40), nullable=False),
    sa.Column("detail", sa.Text, nullable=False),
    sa.Column("happened_at", sa.String(40), nullable=False),
    sa.Column("db_login", sa.String(200)),
    *_chain(),
)

#: PostgreSQL only (revision 0008): the tests as they stand counted per day (UTC, the start's), station, verdict,
#: first test or retest, INVALID area ('' for none) and simulated or not; a trigger counts each first indexing,
#: withdrawals are subtracted where it is read (:mod:`edc_bench.history.day_counts`). Not a record: no login writes
#: it, and it is not append-only (a count goes up).
test_day_counts = sa.Table(
    "test_day_counts", metadata,
    sa.Column("day", sa.String(10), primary_key=True),
    sa.Column("station", sa.String(200), primary_key=True),
    sa.Column("verdict", sa.String(20), primary_key=True),
    sa.Column("first_test", sa.Boolean, primary_key=True),
    sa.Column("invalid_area", sa.String(20), primary_key=True),
    sa.Column("simulated", sa.Boolean, primary_key=True),
    sa.Column("tests", sa.BigInteger, nullable=False),
)

#: PostgreSQL only (revision 0009): the same counts per month (UTC) and pump type (variant and part number), kept by
#: the same trigger: a year's figures sum whole months from these (:mod:`edc_bench.history.day_counts`).
test_month_counts = sa.Table(
    "test_month_counts", metadata,
    sa.Column("month", sa.String(7), primary_key=True),
    sa.Column("station", sa.String(200), primary_key=True),
    sa.Column("variant", sa.String(200), primary_key=True),
    sa.Column("part_number", sa.String(100), primary_key=True),
    sa.Column("verdict", sa.String(20), primary_key=True),
    sa.Column("first_test", sa.Boolean, primary_key=True),
    sa.Column("invalid_area", sa.String(20), primary_key=True),
    sa.Column("simulated", sa.Boolean, primary_key=True),
    sa.Column("tests", sa.BigInteger, nullable=False),
)

#: The append-only tables, in the order they were made.
TABLES = (tests, teardowns, amendments, adoptions, reference_valves, rig_checks, edc_logins, chain_anchors,
          guard_events)

#: The hash-chained tables (:mod:`edc_bench.history.chain`).
CHAINED_TABLES = (tests, teardowns, amendments, adoptions, reference_valves, rig_checks, guard_events)

#: The triggers a SQLite history must have (checked, and restored if missing, whenever it is opened).
SQLITE_TRIGGERS = tuple(f"{t.name}_no_{event}" for t in TABLES for event in ("update", "delete")) + tuple(
    f"{t.name}_chained" for t in CHAINED_TABLES)

#: Columns of a test in listings and CSV exports, in order (what a test is; how it was indexed is in --audit).
COLUMNS = tuple(c.name for c in tests.columns if c.name not in NOT_LISTED)
