"""A history URL's password, in every form SQLAlchemy reads, never shown (issue #51, item 6): not by argparse's
errors (quoted before any command runs), not in a driver's messages, not in a model's or a dataset's metadata; a raw
'@' in it refused in one line; and a password that is also a word of the output (PASS) leaves a listing alone."""

from __future__ import annotations

import io
import json
import os
from pathlib import Path

import pytest
import sqlalchemy as sa
from helpers import edc_bench

from edc_bench.history.secrets import RedactingStream, raw_at_in_password, redact, secrets_of, shown_url
from edc_bench.history.store import COLUMNS, HistoryStore

# Every password is two pieces around the character under test: neither piece may show, so a password cut in two
# (by a raw '@' SQLAlchemy reads as the end of it) is caught too.
A, B = "Kx7qv", "Zw9mj"
CLOSED = "127.0.0.1:9"  # nothing listens there: every command meets a database that is down

#: form -> (URL, its password as SQLAlchemy reads it, or None where SQLAlchemy would misread it: a raw '@')
FORMS: dict[str, tuple[str, str | None]] = {
    "userinfo": (f"postgresql+psycopg://shop:{A}-{B}@{CLOSED}/edc", f"{A}-{B}"),
    "azure-user": (f"postgresql+psycopg://shop@dbserver:{A}-{B}@{CLOSED}/edc", f"{A}-{B}"),
    "encoded-user": (f"postgresql+psycopg://shop%40dbserver:{A}-{B}@{CLOSED}/edc", f"{A}-{B}"),
    "percent-at": (f"postgresql+psycopg://shop:{A}%40{B}@{CLOSED}/edc", f"{A}@{B}"),
    "azure-percent": (f"postgresql+psycopg://shop@dbserver:{A}%40{B}%2F@{CLOSED}/edc", f"{A}@{B}/"),
    "colon": (f"postgresql+psycopg://shop:{A}:{B}@{CLOSED}/edc", f"{A}:{B}"),
    "slash-quote": (f"postgresql+psycopg://shop:{A}/{B}'@{CLOSED}/edc", f"{A}/{B}'"),
    "blank": (f"postgresql+psycopg://shop:{A} {B}@{CLOSED}/edc", f"{A} {B}"),
    "query": (f"postgresql+psycopg://shop@{CLOSED}/edc?password={A}-{B}", f"{A}-{B}"),
    "query-second": (f"postgresql+psycopg://shop@{CLOSED}/edc?connect_timeout=3&password={A}%26{B}", f"{A}&{B}"),
    "raw-at": (f"postgresql+psycopg://shop:{A}@{B}@{CLOSED}/edc", None),
    "raw-at-azure": (f"postgresql+psycopg://shop@dbserver:{A}@{B}@{CLOSED}/edc", None),
    "raw-at-colon": (f"postgresql+psycopg://shop:{A}@{B}:x@{CLOSED}/edc", None),  # was exit 70: port 'x@127...'
    "raw-at-slash": (f"postgresql+psycopg://shop:{A}@{B}/x@{CLOSED}/edc", None),
    "raw-at-question": (f"postgresql+psycopg://shop:{A}@{B}?x@{CLOSED}/edc", None),  # not a query: no key=
}


def _sqlalchemy_password(url: str) -> str:
    parsed = sa.engine.make_url(url)
    return parsed.password if parsed.password is not None else parsed.query["password"]


@pytest.mark.parametrize("form", FORMS)
def test_every_form_is_masked_and_its_password_known(form: str) -> None:
    url, password = FORMS[form]
    shown = shown_url(url)
    assert A not in shown and B not in shown and "***" in shown and CLOSED in shown, shown
    assert shown_url(shown) == shown  # masking twice changes nothing
    if password is None:
        assert raw_at_in_password(url)
        return
    assert not raw_at_in_password(url)
    assert _sqlalchemy_password(url) == password  # the table says what SQLAlchemy reads...
    assert password in secrets_of(url) and password in secrets_of(f"--db={url}")  # ... and that is what is hidden
    message = f"history database {shown}: connection failed: password={password!r} {password}"
    assert A not in redact(message, secrets_of(url)) and B not in redact(message, secrets_of(url))


@pytest.mark.parametrize("url", [
    f"postgresql+psycopg://shop@{CLOSED}/edc",  # no password: .pgpass
    f"postgresql+psycopg://shop@dbserver@{CLOSED}/edc",  # Azure's user, no password
    f"postgresql+psycopg://shop:pw@{CLOSED}/edc?application_name=bench3@shop",  # an '@' in an option
    "sqlite:///var/lib/edc/h@me:x.sqlite",
])
def test_an_at_elsewhere_is_no_raw_at_in_the_password(url: str) -> None:
    assert not raw_at_in_password(url)
    assert shown_url(url) == url.replace(":pw@", ":***@")  # the rest as it was


def test_a_url_sqlalchemy_would_misread_is_refused_before_it_is_used() -> None:
    from edc_bench.errors import ConfigError
    from edc_bench.history.url import check_url

    with pytest.raises(ConfigError, match="raw '@'.*%40") as refused:
        check_url(FORMS["raw-at-colon"][0])  # SQLAlchemy's int() of 'x@127.0.0.1:9' was a traceback, exit 70
    assert A not in str(refused.value) and B not in str(refused.value) and len(str(refused.value).splitlines()) == 1
    with pytest.raises(ConfigError, match="its port is not a number"):
        check_url("postgresql+psycopg://shop@127.0.0.1:54x2/edc")


def _run_form(form: str, argv: tuple[str, ...], how: str, tmp_path: Path) -> tuple[int, str, str]:
    url = FORMS[form][0]
    env = {**os.environ, "EDC_BENCH_DATA_DIR": str(tmp_path / "data")}
    if how == "environment":
        env["EDC_BENCH_HISTORY_URL"] = url
    proc = edc_bench(*(a.replace("URL", url) for a in argv), env=env, cwd=tmp_path, timeout=120)
    return proc.returncode, proc.stdout, proc.stderr


#: command -> (argv, with URL standing for the form's URL; how the URL is given; what the one line says)
COMMANDS: dict[str, tuple[tuple[str, ...], str, str]] = {
    # argparse's errors, printed before any command runs, quoting the arguments
    "unknown-flag": (("variants", "--db", "URL"), "flag", "unrecognized arguments"),
    "mistyped-flag": (("history", "--DB", "URL"), "flag", "unrecognized arguments"),
    "url-as-command": (("URL",), "flag", "invalid choice"),
    # the history reached: a database that is down, or a URL refused before it is used
    "history": (("history", "--db", "URL"), "flag", "history database"),
    "history=": (("history", "--db=URL"), "flag", "history database"),
    "history-env": (("history",), "environment", "history database"),
    "verify-env": (("history", "--verify"), "environment", "history database"),
    "schema": (("history", "--schema", "--db", "URL"), "flag", "history database"),
    "label-list": (("label", "--list", "--db", "URL"), "flag", "history database"),
    "train-env": (("train", "--from-history"), "environment", "history database"),
    "evaluate": (("evaluate", "--from-history", "--db", "URL"), "flag", "history database"),
}
#: the default suite's share (one process each, under a second): argparse's error and --db for every form, the
#: environment for a few; the slow pass runs every other pair
EVERYDAY = {"unknown-flag": FORMS, "history": FORMS, "history-env": ("userinfo", "azure-user", "blank", "raw-at")}


def _check_command(form: str, command: str, tmp_path: Path) -> None:
    """``command`` given ``form``'s URL: no piece of the password in its output, and refused in one line."""
    argv, how, says = COMMANDS[command]
    code, out, err = _run_form(form, argv, how, tmp_path)
    said = out + err
    assert A not in said and B not in said, (form, command, said)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, (form, command, code, said)
    assert err.startswith("edc-bench") and says in err and "Traceback" not in err, (form, command, err)
    if FORMS[form][1] is None and says == "history database":  # a raw '@': how to write it
        assert "raw '@'" in err and "%40" in err, (form, command, err)
    elif says == "history database":
        assert "***" in err and "connection" in err, (form, command, err)


@pytest.mark.parametrize(("form", "command"), [(form, command) for command, forms in EVERYDAY.items()
                                               for form in forms])
def test_no_form_of_password_shows_in_a_command(form: str, command: str, tmp_path: Path) -> None:
    _check_command(form, command, tmp_path)


@pytest.mark.slow  # a process for each form, under a second each
@pytest.mark.parametrize("command", [c for c in COMMANDS if set(FORMS) - set(EVERYDAY.get(c, ()))])
def test_no_form_of_password_shows_in_any_command(command: str, tmp_path: Path) -> None:
    for form in FORMS:
        if form not in EVERYDAY.get(command, ()):
            (tmp_path / form).mkdir()
            _check_command(form, command, tmp_path / form)


def _listed_row(valve: str, verdict: str, day: int = 1) -> dict:
    row = {name: "" for name in COLUMNS if name not in ("id", "record_sha256", "indexed_at", "indexed_by")}
    row.update(record_dir=f"/records/{valve}", started_at=f"2026-05-{day:02d}T08:00:00+00:00", valve_id=valve,
               verdict=verdict, station="bench-3", operator="ana", af_v=0.07, a1_v_s_per_mm=0.0038, af_rel=1.0,
               a1_rel=1.0, probability_faulty=None, distance=None, model_name=None, model_sha256=None,
               coil_r20_ohm=None, coil_in_spec=None, model_fits=None, stop_reason=None, test_s=None, simulated=None)
    return row


def test_a_password_that_is_a_verdict_leaves_the_listings_verdicts(tmp_path: Path) -> None:
    """EDC_BENCH_HISTORY_URL carries the password PASS: a listing of another history (--db) keeps its PASS
    verdicts; the error about the shop's history that is down shows no PASS."""
    url = f"sqlite:///{tmp_path / 'h.sqlite'}"
    with HistoryStore(url) as store:
        for day, (valve, verdict) in enumerate((("V1", "PASS"), ("V2", "FAIL"), ("V3", "PASS")), start=1):
            store.add_row(_listed_row(valve, verdict, day))
    env = {**os.environ, "EDC_BENCH_DATA_DIR": str(tmp_path / "data"),
           "EDC_BENCH_HISTORY_URL": f"postgresql+psycopg://shop:PASS@{CLOSED}/edc"}
    listing = edc_bench("history", "--db", url, env=env)
    assert listing.returncode == 0, listing.stderr
    rows = [line for line in listing.stdout.splitlines() if line.startswith("│")]  # the table's rows
    assert [("PASS" in r, "FAIL" in r) for r in rows] == [(True, False), (False, True), (True, False)], listing.stdout
    assert "***" not in listing.stdout
    as_json = edc_bench("history", "--db", url, "--json", env=env)
    assert [r["verdict"] for r in json.loads(as_json.stdout)] == ["PASS", "FAIL", "PASS"]
    down = edc_bench("history", env=env)
    assert down.returncode == 2 and "PASS" not in down.stdout + down.stderr and "shop:***@" in down.stderr


def _stream(secret_url: str) -> tuple[RedactingStream, io.StringIO]:
    out = io.StringIO()
    return RedactingStream(out, secrets_of(secret_url)), out


def test_the_stream_scrubs_a_password_only_where_it_can_leak() -> None:
    stream, out = _stream(f"postgresql+psycopg://shop:PASS@{CLOSED}/edc")
    stream.write("│ 1  │ V1    │ PASS    │\n")  # a listing: the verdict stays
    print("verdict:", "PASS", file=stream)  # a report line, in four writes
    stream.write("history database postgresql+psycopg://shop:PASS@h/edc: connection failed: password=PASS\n")
    print("FATAL:  password authentication failed for user", '"shop"', "(PASS)", file=stream)
    stream.write("edc-bench: error: unrecognized arguments: --db=postgresql+psycopg://shop:PASS@h/edc\n")
    assert out.getvalue().splitlines() == [
        "│ 1  │ V1    │ PASS    │", "verdict: PASS",
        "history database postgresql+psycopg://shop:***@h/edc: connection failed: password=***",
        'FATAL:  password authentication failed for user "shop" (***)',  # 'password' is no PASS
        "edc-bench: error: unrecognized arguments: --db=postgresql+psycopg://shop:***@h/edc"]


def test_the_stream_scrubs_what_follows_a_traceback_and_a_line_written_in_pieces() -> None:
    stream, out = _stream(f"postgresql+psycopg://shop:{A}-{B}@{CLOSED}/edc")
    stream.write("a driver's ")
    stream.write(f"DSN: host=h password={A}")
    stream.write(f"-{B} user=shop\nnext")
    assert out.getvalue() == "a driver's DSN: host=h password=*** user=shop\n"  # 'next' waits for its line's end
    stream.flush()
    assert out.getvalue().endswith("next")
    stream.write("\nTraceback (most recent call last):\n")
    stream.write(f"  File 'x.py', line 1, in <module>\n    connect('{A}-{B}')\nValueError: {A}-{B}\n")
    assert A not in out.getvalue() and out.getvalue().count("***") == 3


def test_a_short_password_is_masked_in_urls_only() -> None:
    stream, out = _stream(f"postgresql+psycopg://shop:ab@{CLOSED}/edc")
    stream.write("history database postgresql+psycopg://shop:ab@h/edc: a cab\n")
    assert out.getvalue() == "history database postgresql+psycopg://shop:***@h/edc: a cab\n"


@pytest.fixture
def azure_login_url(postgres_db: str) -> str:
    """``postgres_db`` as the login ``ana@shop`` (Azure's user@server), with a password holding an encoded '@', a
    ':' and a '/' (the tests' server trusts every local login: the password is carried, never checked)."""
    engine = sa.create_engine(postgres_db)
    with engine.begin() as conn:
        conn.exec_driver_sql("DO $$ BEGIN IF NOT EXISTS (SELECT FROM pg_roles WHERE rolname = 'ana@shop') THEN "
                             "CREATE ROLE \"ana@shop\" LOGIN SUPERUSER; END IF; END $$")
    engine.dispose()
    return postgres_db.replace("://postgres@", f"://ana@shop:{A}%40{B}:x/y@")


def test_an_azure_login_with_special_characters_reaches_the_history_and_its_dataset_hides_the_password(
        azure_login_url: str) -> None:
    from edc_bench.cli.common import history_label_dataset

    with HistoryStore(azure_login_url) as store:
        assert store.login == "ana@shop"  # SQLAlchemy read the user as Azure writes it
        store.add_row(_listed_row("V1", "PASS"))
        store.add_teardown("V1", "worn", labelled_by="ana", labelled_at="2026-05-02")
        assert A not in store.shown_url and "ana@shop:***@" in store.shown_url
    dataset, where = history_label_dataset(azure_login_url, include_simulated=True)
    kept = json.dumps(dataset.provenance) + where
    assert A not in kept and B not in kept and "ana@shop:***@" in kept
    listing = edc_bench("history", "--db", azure_login_url)
    assert listing.returncode == 0 and "PASS" in listing.stdout and A not in listing.stdout + listing.stderr


@pytest.mark.slow  # trains a candidate (5 folds) on 40 labels
def test_a_model_trained_through_an_azure_login_keeps_the_url_without_its_password(azure_login_url: str,
                                                                                   tmp_path: Path) -> None:
    import numpy as np

    rng = np.random.default_rng(5)
    with HistoryStore(azure_login_url) as store:
        for n in range(40):
            af_rel, a1_rel = rng.uniform(0.8, 1.8, 2)
            row = _listed_row(f"S{n:03d}", "PASS")
            row.update(record_dir=f"/records/S{n:03d}", af_rel=af_rel, a1_rel=a1_rel)
            store.add_row(row)
            store.add_teardown(f"S{n:03d}", "worn" if af_rel + a1_rel > 2.6 else "reusable", labelled_by="ana",
                               labelled_at="2026-05-02")
    env = {**os.environ, "EDC_BENCH_DATA_DIR": str(tmp_path / "station")}
    candidate = tmp_path / "candidate.onnx"
    proc = edc_bench("train", "--from-history", "--db", azure_login_url, "--include-simulated", "--prior-weight", "0",
                     "--candidate-file", str(candidate), env=env)
    assert proc.returncode == 0, proc.stderr
    assert A not in proc.stdout + proc.stderr and B not in proc.stdout + proc.stderr
    written = candidate.read_bytes()
    assert A.encode() not in written and B.encode() not in written and b"ana@shop:***@" in written
