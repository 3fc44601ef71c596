"""Bad input across every command: one clear line naming what was wrong and how to fix it, never a traceback.

The corpus below is what a new user types: wrong numbers, files that are not
what a flag wants, paths that cannot be written, ids that cannot be kept,
databases that are not databases, buses python-can does not have. Each case
runs ``edc_bench.cli.main`` in process (a subprocess costs a second), with
the long-running work of every command replaced by a tripwire: bad input
must be refused before any work starts, so a case that reaches the work is
a failure, not a slow test. Two subprocess runs cover what only the real
interpreter shows (bytes that are not UTF-8 in argv, python-can reading
``CAN_INTERFACE`` in a fresh process).
"""

from __future__ import annotations

import os
import re
import socket
import stat
import subprocess
import sys
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from helpers import REPO, run_cli

from edc_bench.cli import COMMANDS, build_parser
from edc_bench.cli.exit_codes import (
    COMMAND_CODES,
    MEANINGS,
    ExitCode,
    command_codes,
    exit_codes_sentence,
)

DEFAULT_TOML = (REPO / "configs" / "p-edc-default.toml").read_text(encoding="utf-8")
FOLDER = object()  # a file entry that is a folder
FIFO = object()  # a file entry that is a named pipe: a special file like /dev/null, but harmless to clobber
BUSY_PORT = "{busy_port}"  # replaced by a port another socket listens on


def variant_with(**changes: str) -> str:
    """The default variant's text with ``key = value`` lines replaced (``mass_kg="1e308"``), renamed ``bad``."""
    text = DEFAULT_TOML.replace('name = "p-edc-default"', 'name = "bad"')
    for key, value in changes.items():
        text, n = re.subn(rf"^{key} = [^\n#]*", f"{key} = {value}", text, count=1, flags=re.MULTILINE)
        assert n == 1, key
    return text


def record_json(**fields: object) -> str:
    """A small record.json (enough for the commands that read only its head)."""
    import json

    return json.dumps({"verdict": "PASS", "variant": "p-edc-default", "valve_id": "V-1",
                       "features": {"af": 0.07, "a1": 0.0038}, **fields})


@dataclass(frozen=True)
class Case:
    """One bad input: the command line, what to prepare, the exit code and the words the message must hold."""

    argv: tuple[str, ...]
    code: int
    words: tuple[str, ...]
    files: Mapping[str, object] = field(default_factory=dict)  # path -> text, bytes or FOLDER
    env: Mapping[str, str] = field(default_factory=dict)


def case(argv: str | tuple[str, ...], code: int, *words: str, files: Mapping[str, object] | None = None,
         env: Mapping[str, str] | None = None) -> Case:
    return Case(tuple(argv.split()) if isinstance(argv, str) else argv, code, words, files or {}, env or {})


BAD = ExitCode.BAD_INPUT
BINARY = bytes(range(256)) * 4
LATIN1 = DEFAULT_TOML.replace("P-EDC-like in-line pump", "Einspritzpumpe für den Prüfstand").encode("latin-1")
UTF16 = DEFAULT_TOML.encode("utf-16")
LONG_ID = "V" * 101
NOT_UTF8 = "V-\udcff1"  # how Python hands over the bytes b"V-\xff1" from a UTF-8 command line
TEXT = "these are notes, not a database\n"
GARBAGE_RECORD = {"rec/record.json": "[]"}
RECORD = {"rec/record.json": record_json()}

CORPUS: dict[str, Case] = {
    # -- test ----------------------------------------------------------------------------------------------------
    "test-seed-negative": case("test --seed -1", BAD, "--seed", "-1", "0 or more"),
    "test-seed-not-a-number": case("test --seed abc", BAD, "--seed", "abc", "whole number"),
    "test-variant-binary": case("test --variant bin.toml", BAD, "bin.toml", "binary"),
    "test-variant-latin1": case("test --variant latin1.toml", BAD, "latin1.toml", "not UTF-8", "save"),
    "test-variant-utf16": case("test --variant utf16.toml", BAD, "UTF-16", "save it as UTF-8"),
    "test-variant-empty": case("test --variant empty.toml", BAD, "empty.toml", "empty", "p-edc-default.toml"),
    "test-variant-folder": case("test --variant dir.toml", BAD, "dir.toml", "folder"),
    "test-variant-device": case("test --variant /dev/null", BAD, "/dev/null", "device"),
    "test-mass-huge": case("test --variant m.toml", BAD, "mass_kg", "1e+308", "implausible", "10 kg"),
    "test-stroke-huge": case("test --variant s.toml", BAD, "stroke_mm", "implausible", "60 mm"),
    "test-spring-tiny": case("test --variant k.toml", BAD, "spring_n_per_mm", "implausible"),
    "test-coil-huge": case("test --variant r.toml", BAD, "resistance_ohm", "implausible", "ohm"),
    "test-period-long": case("test --variant p.toml", BAD, "period_s", "100 Hz to 10 kHz"),
    "test-duration-huge": case("test --duration-s 1e9", BAD, "--duration-s", "600"),
    "test-duration-nan": case("test --duration-s nan", BAD, "--duration-s", "finite"),
    "test-out-is-a-file": case("test --out afile", BAD, "--out", "afile", "not a folder"),
    "test-out-dev-null": case("test --out /dev/null", BAD, "--out", "/dev/null", "device"),
    "test-out-cannot-make": case("test --out /sys/edc-records", BAD, "--out", "cannot make", "writable"),
    "test-out-not-writable": case("test --out /proc", BAD, "--out", "/proc", "not writable"),
    "test-valve-id-long": case(("test", "--valve-id", LONG_ID), BAD, "--valve-id", "101 characters", "at most 100",
                               "...' is"),  # the id shown cut short, its quotes closed
    "test-valve-id-not-utf8": case(("test", "--valve-id", NOT_UTF8), BAD, "--valve-id", "UTF-8"),
    "test-valve-id-line-break": case(("test", "--valve-id", "V-1\nV-2"), BAD, "--valve-id", "control character"),
    "test-pump-serial-long": case(("test", "--pump-serial", "P" * 300), BAD, "--pump-serial", "at most 100"),
    "test-operator-not-utf8": case(("test", "--operator", NOT_UTF8), BAD, "--operator", "UTF-8"),
    "test-db-missing-folder": case("test --db sqlite:///nodir/h.sqlite", BAD, "nodir", "does not exist", "mkdir"),
    "test-history-db-alias": case("test --history-db sqlite:///nodir/h.sqlite", BAD, "nodir", "does not exist"),
    "test-db-not-a-database": case("test --db sqlite:///notes.txt", BAD, "notes.txt", "not a SQLite database"),
    "test-db-a-path": case("test --db history.sqlite", BAD, "history.sqlite", "sqlite:///history.sqlite"),
    "test-db-env-missing-folder": case("test", BAD, "EDC_BENCH_HISTORY_URL", "does not exist",
                                       env={"EDC_BENCH_HISTORY_URL": "sqlite:///nodir/h.sqlite"}),
    "test-interface-unknown": case("test --interface nosuchbus", BAD, "--interface", "nosuchbus", "socketcan"),
    "test-channel-alone": case("test --channel can0", BAD, "--channel can0", "needs --interface", "socketcan"),
    "test-can-interface-env": case("test", BAD, "CAN_INTERFACE", "nosuchbus", "socketcan",
                                   env={"CAN_INTERFACE": "nosuchbus"}),
    "test-can-bitrate-env": case("test", BAD, "CAN_BITRATE", "bit rate",
                                 env={"CAN_INTERFACE": "virtual", "CAN_BITRATE": "fast"}),
    "test-bitrate-negative": case("test --interface virtual --bitrate -500", BAD, "--bitrate", "10000 to 1000000"),
    "test-bitrate-alone": case("test --bitrate 250000", BAD, "--bitrate", "--interface"),
    "test-adapter-unknown": case("test --adapter warp", BAD, "--adapter", "warp"),
    "test-coil-temp-inf": case("test --coil-temp-c inf", BAD, "--coil-temp-c", "plausible"),
    "test-valve-spec-unknown": case("test --valve cracked", BAD, "--valve", "cracked"),
    "test-unknown-flag": case("test --frobnicate", BAD, "--frobnicate", "--help"),
    # -- rig -----------------------------------------------------------------------------------------------------
    "rig-listen-foreign-address": case("rig --listen 203.0.113.7:5000", BAD, "--listen", "203.0.113.7",
                                       "not an address of this machine"),
    "rig-listen-bad-address": case("rig --listen 999.1.1.1:5000", BAD, "--listen", "999.1.1.1"),
    "rig-listen-port-in-use": case(f"rig --listen 127.0.0.1:{BUSY_PORT}", BAD, "--listen", "in use", "0 for any"),
    "rig-listen-port-range": case("rig --listen 127.0.0.1:70000", BAD, "--listen", "70000", "0..65535"),
    "rig-no-place": case("rig", BAD, "--listen", "--pty"),
    "rig-seed-negative": case("rig --listen 127.0.0.1:0 --seed -1", BAD, "--seed", "0 or more"),
    "rig-variant-binary": case("rig --listen 127.0.0.1:0 --variant bin.toml", BAD, "bin.toml", "binary"),
    # -- variants ------------------------------------------------------------------------------------------------
    "variants-broken-station-file": case("variants", ExitCode.OK, "latin1", "cannot be used", "not UTF-8",
                                         env={"EDC_BENCH_VARIANTS_DIR": "station"}),
    "variants-dir-is-a-file": case("variants", BAD, "EDC_BENCH_VARIANTS_DIR", "not a folder",
                                   env={"EDC_BENCH_VARIANTS_DIR": "afile"}),
    "variants-extra-argument": case("variants all", BAD, "unrecognized arguments", "all"),
    # -- tune ----------------------------------------------------------------------------------------------------
    "tune-mass-huge": case("tune --variant m.toml", BAD, "mass_kg", "implausible"),
    "tune-variant-binary": case("tune --variant bin.toml", BAD, "binary"),
    "tune-variant-unknown": case("tune --variant p-edc-nope", BAD, "unknown variant", "p-edc-default"),
    # -- calibrate -----------------------------------------------------------------------------------------------
    "calibrate-tests-zero": case("calibrate --tests 0", BAD, "--tests", "1 or more"),
    "calibrate-tests-negative": case("calibrate --tests -3", BAD, "--tests", "1 or more"),
    "calibrate-seed-negative": case("calibrate --seed -1", BAD, "--seed", "0 or more"),
    "calibrate-baseline-device": case("calibrate --write --baseline-file fifo", BAD, "--baseline-file", "fifo",
                                      "device"),
    "calibrate-baseline-folder": case("calibrate --baseline-file adir", BAD, "--baseline-file", "is a folder"),
    "calibrate-baseline-not-writable": case("calibrate --baseline-file /proc/b.toml", BAD, "/proc", "writable"),
    "calibrate-out-a-file": case("calibrate --valve new --out afile", BAD, "--out", "not a folder"),
    "calibrate-out-a-toml": case("calibrate --out b.toml", BAD, "--out", "--baseline-file"),
    "calibrate-interface-unknown": case("calibrate --interface nosuchbus", BAD, "--interface", "socketcan"),
    "calibrate-channel-alone": case("calibrate --channel can0", BAD, "--channel", "needs --interface"),
    "calibrate-valve-id-long": case(("calibrate", "--valve-id", LONG_ID), BAD, "--valve-id", "at most 100"),
    "calibrate-valve-worn": case("calibrate --valve worn", BAD, "--valve worn", "not a new valve"),
    "calibrate-write-and-append": case("calibrate --write --append", BAD, "--append", "not allowed"),
    # -- train ---------------------------------------------------------------------------------------------------
    "train-count-zero": case("train --count 0", BAD, "--count", "1 or more"),
    "train-count-small": case("train --count 5", BAD, "--count", "at least 20"),
    "train-seed-negative": case("train --seed -7", BAD, "--seed", "0 or more"),
    "train-marginal-band-negative": case("train --marginal-band -1", BAD, "--marginal-band", "0 or more"),
    "train-models-dir-a-file": case("train --models-dir afile", BAD, "--models-dir", "not a folder"),
    "train-out-dir-alias-dev-null": case("train --out-dir /dev/null", BAD, "--models-dir", "device"),
    "train-dataset-missing": case("train --dataset none.npz", BAD, "--dataset", "no such file"),
    "train-dataset-not-a-dataset": case("train --dataset notes.txt", BAD, "notes.txt", "not an edc-bench dataset"),
    "train-save-dataset-folder": case("train --save-dataset adir", BAD, "--save-dataset", "is a folder"),
    "train-variants-unknown": case("train --variants p-edc-nope", BAD, "unknown variant"),
    "train-candidate-folder": case("train --from-history --candidate-file adir", BAD, "--candidate-file", "folder"),
    "train-db-missing-folder": case("train --from-history --db sqlite:///nodir/h.sqlite", BAD, "nodir",
                                    "does not exist"),
    "train-adopt-missing": case("train --adopt none.onnx", BAD, "--adopt", "no such model file"),
    "train-adopt-not-a-model": case("train --adopt notes.txt", BAD, "notes.txt", "cannot be loaded"),
    "train-name-bad": case("train --from-history --name ../x", BAD, "--name", "letters, digits"),
    # -- classify ------------------------------------------------------------------------------------------------
    "classify-af-negative": case("classify --af -0.07 --a1 0.0038", BAD, "--af", "above 0"),
    "classify-af-nan": case("classify --af nan --a1 0.0038", BAD, "--af", "finite"),
    "classify-a1-inf": case("classify --af 0.07 --a1 inf", BAD, "--a1", "finite"),
    "classify-af-huge": case("classify --af 1e300 --a1 0.0038", BAD, "--af", "times the new-valve baseline", "in V"),
    "classify-a1-tiny": case("classify --af 0.07 --a1 1e-12", BAD, "--a1", "times the new-valve baseline"),
    "classify-nothing": case("classify", BAD, "--af", "record folder"),
    "classify-record-and-values": case("classify rec --af 0.07 --a1 0.0038", BAD, "either", files=RECORD),
    "classify-record-garbage": case("classify rec", BAD, "record.json", "not an edc-bench record",
                                    files=GARBAGE_RECORD),
    "classify-record-no-features": case("classify rec", BAD, "rec", "no features",
                                        files={"rec/record.json": '{"verdict": "PASS"}'}),
    "classify-record-missing": case("classify nodir", BAD, "nodir", "no such record folder"),
    "classify-model-missing": case("classify --af 0.07 --a1 0.0038 --model none.onnx", BAD, "none.onnx", "not found"),
    # -- evaluate ------------------------------------------------------------------------------------------------
    "evaluate-count-zero": case("evaluate --count 0", BAD, "--count", "1 or more"),
    "evaluate-count-negative": case("evaluate --count -5", BAD, "--count", "1 or more"),
    "evaluate-seed-negative": case("evaluate --seed -1", BAD, "--seed", "0 or more"),
    "evaluate-variants-unknown": case("evaluate --variants p-edc-nope", BAD, "unknown variant"),
    "evaluate-model-missing": case("evaluate --model none.onnx", BAD, "none.onnx", "not found"),
    "evaluate-db-not-a-database": case("evaluate --from-history --db sqlite:///notes.txt", BAD,
                                       "not a SQLite database"),
    # -- paper ---------------------------------------------------------------------------------------------------
    "paper-figure-device": case("paper --figure fifo", BAD, "--figure", "device"),
    "paper-figure-folder": case("paper --figure adir", BAD, "--figure", "is a folder"),
    "paper-figure-missing-folder": case("paper --figure nodir/f.png", BAD, "--figure", "does not exist"),
    "paper-figure-not-png": case("paper --figure fig.pdf", BAD, "--figure", ".png"),
    "paper-figure-not-writable": case("paper --figure /proc/f.png", BAD, "--figure", "not writable"),
    "paper-runs-zero": case("paper --runs 0", BAD, "--runs", "1 or more"),
    "paper-seed-negative": case("paper --seed -2010", BAD, "--seed", "0 or more"),
    "paper-variant-unknown": case("paper --variant p-edc-nope", BAD, "unknown variant"),
    # -- study-boundary ------------------------------------------------------------------------------------------
    "study-boundary-count-zero": case("study-boundary --count 0", BAD, "--count", "1 or more"),
    "study-boundary-figure-folder": case("study-boundary --figure adir", BAD, "--figure", "is a folder"),
    "study-boundary-figure-cannot-write": case("study-boundary --figure /sys/t.png", BAD, "--figure", "writable"),
    "study-boundary-model-missing": case("study-boundary --model none.onnx", BAD, "none.onnx", "not found"),
    "study-boundary-db-missing-folder": case("study-boundary --from-history --db sqlite:///nodir/h.sqlite", BAD,
                                             "nodir", "does not exist"),
    # -- perf ----------------------------------------------------------------------------------------------------
    "perf-variant-unknown": case("perf --variant p-edc-nope", BAD, "unknown variant"),
    "perf-variant-latin1": case("perf --variant latin1.toml", BAD, "not UTF-8"),
    "perf-only-unknown": case("perf --only everything", BAD, "--only", "everything"),
    # -- replay --------------------------------------------------------------------------------------------------
    "replay-nothing": case("replay", BAD, "record folder", "--can-log"),
    "replay-folder-missing": case("replay nodir", BAD, "nodir", "no such record folder"),
    "replay-record-garbage": case("replay rec", BAD, "not an edc-bench record", files=GARBAGE_RECORD),
    "replay-log-missing": case("replay --can-log none.log --variant p-edc-default", BAD, "none.log"),
    "replay-log-binary": case("replay --can-log junk.log --variant p-edc-default", BAD, "junk.log"),
    "replay-log-unknown-format": case("replay --can-log notes.txt --variant p-edc-default", BAD, "notes.txt", ".asc"),
    "replay-log-without-variant": case("replay --can-log junk.log", BAD, "--variant"),
    # -- history -------------------------------------------------------------------------------------------------
    "history-db-missing-folder": case("history --db sqlite:///nodir/h.sqlite", BAD, "nodir", "does not exist",
                                      "mkdir"),
    "history-db-not-a-database": case("history --db sqlite:///notes.txt", BAD, "notes.txt", "not a SQLite database"),
    "history-db-a-folder": case("history --db sqlite:///adir", BAD, "adir", "is a folder"),
    "history-db-device": case("history --db sqlite:///fifo", BAD, "fifo", "device"),
    "history-db-unknown-dialect": case("history --db nosuchdb://host/x", BAD, "nosuchdb", "sqlite:///"),
    "history-csv-folder": case("history --csv adir", BAD, "--csv", "is a folder"),
    "history-csv-device": case("history --csv fifo", BAD, "--csv", "device"),
    "history-csv-missing-folder": case("history --csv nodir/t.csv", BAD, "--csv", "does not exist"),
    "history-plot-folder": case("history --trend V-1 --plot adir", BAD, "--plot", "is a folder"),
    "history-plot-not-png": case("history --trend V-1 --plot t.svg", BAD, "--plot", ".png"),
    "history-plot-without-trend": case("history --plot t.png", BAD, "--plot", "--trend"),
    "history-limit-zero": case("history --limit 0", BAD, "--limit", "1 or more"),
    "history-since-not-a-date": case("history --since yesterday", BAD, "--since", "YYYY-MM-DD"),
    "history-valve-id-long": case(("history", "--valve-id", LONG_ID), BAD, "--valve-id", "at most 100"),
    "history-valve-alias-not-utf8": case(("history", "--valve", NOT_UTF8), BAD, "--valve", "UTF-8"),
    "history-trend-control": case(("history", "--trend", "V\x1b[2J"), BAD, "--trend", "control character"),
    "history-add-missing": case("history --add nodir", BAD, "nodir", "no such record folder"),
    "history-add-garbage": case("history --add rec", BAD, "not an edc-bench record", files=GARBAGE_RECORD),
    # a record an older edc-bench wrote with bytes that are not UTF-8: indexed (escaped), never a crash
    "history-add-not-utf8-record": case("history --add rec", ExitCode.OK, "indexed 1 new record folder",
                                        files={"rec/record.json": record_json(valve_id=NOT_UTF8, verdict="UNCLASSIFIED")}),
    # -- label ---------------------------------------------------------------------------------------------------
    "label-db-missing-folder": case("label V-1 --finding worn --db sqlite:///nodir/h.sqlite", BAD, "nodir",
                                    "does not exist"),
    "label-no-finding": case("label V-1", BAD, "--finding"),
    "label-valve-never-tested": case("label V-9999 --finding reusable", BAD, "no test of valve 'V-9999'",
                                     "--new-valve"),
    "history-db-unknown-dialect-named": case("history --db foo://bar", BAD, "'foo' is not a database", "sqlite:///FILE",
                                       "postgresql+psycopg"),
    "label-finding-unknown": case("label V-1 --finding broken", BAD, "--finding", "broken"),
    "label-clearance-negative": case("label V-1 --finding worn --clearance-mm -0.1", BAD, "--clearance-mm"),
    "label-date-future": case("label V-1 --finding worn --date 2999-01-01", BAD, "--date", "future"),
    "label-id-long": case(("label", LONG_ID, "--finding", "worn"), BAD, "VALVE_ID", "at most 100"),
    "label-id-blank": case(("label", "  ", "--finding", "worn"), BAD, "VALVE_ID", "empty"),
    "label-id-not-utf8": case(("label", NOT_UTF8, "--finding", "worn"), BAD, "VALVE_ID", "UTF-8"),
    "label-by-not-utf8": case(("label", "V-1", "--finding", "worn", "--by", NOT_UTF8), BAD, "--by", "UTF-8"),
    "label-delete-zero": case("label --delete 0", BAD, "--delete", "1 or more"),
    # -- report --------------------------------------------------------------------------------------------------
    "report-folder-missing": case("report nodir", BAD, "nodir", "no such record folder"),
    "report-not-a-record": case("report adir", BAD, "adir", "no record.json"),
    "report-out-a-file": case("report rec --out afile", BAD, "--out", "not a folder", files=RECORD),
    "report-out-dev-null": case("report rec --out /dev/null", BAD, "--out", "device", files=RECORD),
    "report-record-not-utf8": case("report rec", BAD, "valve_id", "not valid text", "record.json",
                                   files={"rec/record.json": record_json(valve_id=NOT_UTF8)}),
    "report-out-cannot-make": case("report rec --out /sys/reports", BAD, "--out", "cannot make", files=RECORD),
    # -- check-station -------------------------------------------------------------------------------------------
    "check-station-duration-zero": case("check-station --duration-s 0", BAD, "--duration-s", "0.5 and 600"),
    "check-station-duration-nan": case("check-station --duration-s nan", BAD, "--duration-s"),
    "check-station-variant-utf16": case("check-station --variant utf16.toml", BAD, "UTF-16"),
    # -- rig-check --------------------------------------------------------------------------------------------------
    "rig-check-break-unknown": case("rig-check --break late-replies", BAD, "--break", "no-watchdog"),
    "rig-check-break-on-a-bus": case("rig-check --break no-watchdog --interface virtual --channel x", BAD,
                                     "simulated rig only"),
    "rig-check-c-with-a-break": case("rig-check --firmware c --break no-watchdog", BAD, "Python firmware"),
    "rig-check-commands-few": case("rig-check --commands 5", BAD, "--commands", "100 to 100000"),
    "rig-check-out-is-a-file": case("rig-check --out afile", BAD, "--out", "a file is there"),
    "rig-check-variant-utf16": case("rig-check --variant utf16.toml", BAD, "UTF-16"),
    "rig-check-no-such-bus": case("rig-check --interface nosuchbus --channel x", BAD, "nosuchbus"),
    # -- session ----------------------------------------------------------------------------------------------------
    "session-not-a-terminal": case("session", BAD, "needs a terminal", "edc-bench test"),
    "session-variant-utf16": case("session --variant utf16.toml", BAD, "UTF-16"),
    "session-out-is-a-file": case("session --out afile", BAD, "--out", "is a file, not a folder"),
    "session-operator-too-long": case(("session", "--operator", LONG_ID), BAD, "--operator", "100"),
    # -- rig-selfcheck, and the simulated rig's drift ------------------------------------------------------------------
    "rig-selfcheck-drift-unknown-key": case("rig-selfcheck --rig-drift lvdt_offset=0.05", BAD, "--rig-drift",
                                            "is not a drift", "lvdt_offset_mm=0.05"),
    "rig-selfcheck-drift-absurd": case("rig-selfcheck --rig-drift current_gain=3", BAD, "--rig-drift",
                                       "outside 0.5..1.5"),
    "rig-selfcheck-drift-on-a-bus": case("rig-selfcheck --rig-drift lvdt_gain=1.02 --interface virtual --channel x",
                                         BAD, "--rig-drift", "simulated rig"),
    "rig-selfcheck-register-without-id": case("rig-selfcheck --register", BAD, "--register needs --valve-id"),
    "rig-selfcheck-id-without-register": case("rig-selfcheck --valve-id REF-1", BAD, "--valve-id goes with --register"),
    "rig-selfcheck-register-bad-valve": case("rig-selfcheck --register --valve-id R --valve clearance=abc", BAD,
                                             "clearance"),
    "rig-selfcheck-db-missing-folder": case("rig-selfcheck --db sqlite:///nodir/h.sqlite", BAD, "nodir"),
    "test-rig-drift-not-a-number": case("test --rig-drift lvdt_gain=abc", BAD, "--rig-drift", "not a number"),
    "rig-rig-drift-twice": case("rig --listen 127.0.0.1:0 --rig-drift lvdt_gain=1.1,lvdt_gain=1.2", BAD,
                                "--rig-drift", "given twice"),
    "history-station-with-trend": case("history --station bench1 --trend V-1", BAD,
                                       "--station goes with a listing or --summary"),
    "web-certfile-alone": case("web --certfile cert.pem", BAD, "--certfile and --keyfile go together"),
    "web-sqlite-on-every-address": case("web --db sqlite:///h.sqlite --host 0.0.0.0", BAD,
                                        "served on 127.0.0.1 only", "--allow-remote", files={"h.sqlite": b""}),
    "web-remote-without-https": case("web --db sqlite:///h.sqlite --host 0.0.0.0 --allow-remote", BAD,
                                     "--allow-remote serves HTTPS only", files={"h.sqlite": b""}),
    "history-summary-with-trend": case("history --summary --trend V-1", BAD, "--summary and --trend are separate"),
    # -- a second corpus, a newcomer's: what the system refuses, absurd counts, look-alike ids, mistyped URLs ----------
    "test-out-name-too-long": case(("test", "--out", "a" * 300), BAD, "too long", "shorter"),
    "test-variant-name-too-long": case(("test", "--variant", "a" * 300 + ".toml"), BAD, "too long", "shorter"),
    "report-name-too-long": case(("report", "a" * 300), BAD, "too long"),
    "history-csv-name-too-long": case(("history", "--csv", "a" * 300 + ".csv"), BAD, "too long"),
    "history-db-name-too-long": case(("history", "--db", "sqlite:///" + "a" * 300), BAD, "too long"),
    "replay-log-name-too-long": case(("replay", "--can-log", "a" * 300 + ".log", "--variant", "p-edc-default"), BAD,
                                     "too long"),
    "classify-model-name-too-long": case(("classify", "--af", "0.07", "--a1", "0.0038", "--model", "a" * 300),
                                         BAD, "too long"),
    "history-limit-huge": case("history --limit 99999999999999999999", BAD, "--limit", "at most"),
    "label-delete-huge": case("label --delete 99999999999999999999", BAD, "--delete", "at most"),
    "paper-seed-too-big": case("paper --seed 4294967295 --runs 2", BAD, "--seed", "at most 2147483647"),
    "paper-runs-huge": case("paper --runs 1000000", BAD, "--runs", "at most 100"),
    "calibrate-tests-huge": case("calibrate --tests 99999999999 --valve new", BAD, "--tests", "at most 100"),
    "train-count-huge": case("train --count 999999999999", BAD, "--count", "at most 20000"),
    "evaluate-count-huge": case("evaluate --count 99999999", BAD, "--count", "at most 20000"),
    "study-boundary-count-huge": case("study-boundary --count 99999999", BAD, "--count", "at most 20000"),
    "test-bitrate-huge": case("test --interface virtual --bitrate 99999999999999999999", BAD, "--bitrate",
                              "1000000"),
    "test-valve-id-blank": case(("test", "--valve-id", "   "), BAD, "--valve-id", "blank"),
    "test-valve-id-zero-width": case(("test", "--valve-id", "\u200b"), BAD, "--valve-id", "invisible"),
    "test-valve-id-rtl-override": case(("test", "--valve-id", "V-\u202eevil"), BAD, "--valve-id", "invisible"),
    "test-valve-twice": case("test --valve clearance=0.1,clearance=0.3", BAD, "clearance", "twice"),
    # an interface that lacks an argument it requires cannot open: a bus error, said before any work
    "test-slcan-without-channel": case("test --interface slcan", ExitCode.RIG_ERROR, "needs --channel", "socket://"),
    "test-interface-empty": case(("test", "--interface", ""), BAD, "--interface is empty"),
    "history-db-mistyped-file": case("history --db sqlite:///typo-histroy.sqlite", BAD, "no history at",
                                     "nothing was created"),
    "label-db-mistyped-file": case("label V-2 --finding worn --db sqlite:///typo.sqlite", BAD, "no history at"),
    "history-db-in-memory": case("history --db sqlite://", BAD, "in memory"),
    "history-db-query": case("history --db sqlite:///h.sqlite?mode=ro", BAD, "after '?'"),
    "history-since-after-until": case("history --since 2026-12-01 --until 2026-01-01", BAD, "after --until"),
    "history-data-dir-a-file": case("history", BAD, "EDC_BENCH_DATA_DIR", "afile", env={"EDC_BENCH_DATA_DIR": "afile"}),
    "tune-write-shipped": case("tune --variant p-edc-default --write", BAD, "shipped variant", "copy it"),
    # -- the command itself --------------------------------------------------------------------------------------
    "no-command": case((), BAD, "COMMAND", "required"),
    "unknown-command": case("bogus", BAD, "bogus", "invalid choice"),
}

#: Files every case finds in its working folder (a case's own ``files`` come on top).
COMMON_FILES: dict[str, object] = {
    "bin.toml": BINARY, "latin1.toml": LATIN1, "utf16.toml": UTF16, "empty.toml": "", "dir.toml": FOLDER,
    "m.toml": variant_with(mass_kg="1e308"), "s.toml": variant_with(stroke_mm="1e9"),
    "k.toml": variant_with(spring_n_per_mm="1e-9"), "p.toml": variant_with(period_s="1.0"),
    "r.toml": variant_with(resistance_ohm="5000.0"),
    "afile": TEXT, "notes.txt": TEXT, "adir": FOLDER, "fifo": FIFO, "junk.log": BINARY, "station/latin1.toml": LATIN1,
}


class WorkStarted(AssertionError):
    """A command reached its real work with bad input: it must have refused before."""


def _tripwire(*_args: object, **_kwargs: object) -> None:
    raise WorkStarted("bad input reached the command's work; it must be refused before any work starts")


#: The long-running work of every command (what bad input must never reach).
WORK = ("edc_bench.bench.run_bench_test", "edc_bench.bench.run_simulated_test", "edc_bench.sim.process.rig_process",
        "edc_bench.sim.server.SlcanRigServer.serve_forever", "edc_bench.learning.dataset.make_dataset",
        "edc_bench.learning.dataset.cached_dataset", "edc_bench.experiments.studies.paper_experiment",
        "edc_bench.population.calibrate.population_tests", "edc_bench.station.check_station",
        "edc_bench.perf.suite.run", "edc_bench.control.tuning.tune_pid",
        "edc_bench.learning.shop_training.train_from_labels", "edc_bench.records.report.draw_report",
        "edc_bench.selfcheck.measure.measure_rest")


@pytest.fixture()
def station(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """A fresh working folder and station (data, cache, variants), python-can unconfigured, the work tripwired."""
    for name, value in (("EDC_BENCH_DATA_DIR", tmp_path / "data"), ("EDC_BENCH_CACHE_DIR", tmp_path / "cache")):
        monkeypatch.setenv(name, str(value))
    for name in ("EDC_BENCH_HISTORY_URL", "EDC_BENCH_VARIANTS_DIR", "CAN_INTERFACE", "CAN_CHANNEL", "CAN_BITRATE",
                 "CAN_CONFIG"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setattr("can.util.CONFIG_FILES", [])  # no ~/.canrc or /etc/can.conf of this machine
    for work in WORK:
        monkeypatch.setattr(work, _tripwire)
    monkeypatch.chdir(tmp_path)
    yield tmp_path
    # Writing "to /dev/null" by replacing it (an atomic write, as root) would break the machine: the cases that
    # write use a named pipe instead, and this says at once if anything ever touched the real one.
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode), "/dev/null is no longer a device: restore it (mknod)"


def _prepare(folder: Path, files: Mapping[str, object]) -> None:
    for name, content in files.items():
        path = folder / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if content is FOLDER:
            path.mkdir(exist_ok=True)
        elif content is FIFO:
            os.mkfifo(path)
        elif isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(str(content), encoding="utf-8")


@pytest.fixture()
def busy_port() -> Iterator[int]:
    with socket.create_server(("127.0.0.1", 0)) as server:
        server.listen()
        yield server.getsockname()[1]


@pytest.mark.parametrize("name", list(CORPUS))
def test_bad_input_is_refused_in_one_clear_line(name: str, station: Path, busy_port: int,
                                                 monkeypatch: pytest.MonkeyPatch,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    bad = CORPUS[name]
    _prepare(station, {**COMMON_FILES, **bad.files})
    for key, value in bad.env.items():
        monkeypatch.setenv(key, value)
    argv = [word.replace(BUSY_PORT, str(busy_port)) for word in bad.argv]
    code, out, err = run_cli(argv, capsys)
    said = out + err
    assert "Traceback" not in said and code != ExitCode.INTERNAL_ERROR, said
    assert code == bad.code, f"exit {code}, expected {bad.code}: {said}"
    message = err if code == BAD else said
    missing = [w for w in bad.words if w.lower() not in message.lower()]
    assert not missing, f"{missing} not in: {message}"
    if code == BAD:
        lines = [line for line in err.splitlines() if line.strip()]
        assert len(lines) == 1, f"one line, not {len(lines)}: {err}"


def test_the_corpus_spans_every_command() -> None:
    covered = {bad.argv[0] for bad in CORPUS.values() if bad.argv and bad.argv[0] in COMMANDS}
    assert covered == set(COMMANDS)
    assert len(CORPUS) >= 60


# -- what only a real process shows ---------------------------------------------------------------------------------


def test_bytes_that_are_not_utf8_in_argv_are_refused(tmp_path: Path) -> None:
    env = {**os.environ, "EDC_BENCH_DATA_DIR": str(tmp_path / "data"), "LC_ALL": "C.UTF-8"}
    proc = subprocess.run([sys.executable, "-m", "edc_bench", "test", "--valve-id", b"V-\xff1", "--no-history"],
                          capture_output=True, cwd=tmp_path, env=env, timeout=60)
    err = proc.stderr.decode("utf-8", "replace")
    assert proc.returncode == 2 and "--valve-id" in err and "UTF-8" in err and "Traceback" not in err, err
    assert not (tmp_path / "records").exists()  # refused before the test made anything


def test_a_bad_can_interface_in_the_environment_is_bad_input(tmp_path: Path) -> None:
    env = {**os.environ, "EDC_BENCH_DATA_DIR": str(tmp_path / "data"), "CAN_INTERFACE": "nosuchbus"}
    proc = subprocess.run([sys.executable, "-m", "edc_bench", "test", "--no-history"], capture_output=True, text=True,
                          cwd=tmp_path, env=env, timeout=60)
    assert proc.returncode == 2, proc.stderr
    assert "CAN_INTERFACE 'nosuchbus'" in proc.stderr and "socketcan" in proc.stderr
    assert "Traceback" not in proc.stderr


# -- one command line: help, exit codes, README --------------------------------------------------------------------


@pytest.mark.parametrize("command", COMMANDS)
def test_every_help_ends_with_the_exit_codes_it_can_return(command: str, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run_cli([command, "--help"], capsys)
    assert code == 0
    tail = out[out.rindex("exit codes:"):].splitlines()[1:]
    listed = [int(line.split()[0]) for line in tail if line.strip()]
    assert listed == command_codes(command)
    assert {ExitCode.BAD_INPUT, ExitCode.INTERNAL_ERROR, ExitCode.INTERRUPTED} <= set(listed)


def test_readme_and_the_command_line_doc_state_the_exit_codes_as_they_are() -> None:
    readme = " ".join((REPO / "README.md").read_text(encoding="utf-8").split())
    assert exit_codes_sentence() in readme
    doc = (REPO / "docs" / "command-line.md").read_text(encoding="utf-8")
    rows = dict(re.findall(r"^\| `(\d+)` \| ([^|]+) \|", doc, re.MULTILINE))
    assert {int(k): v.strip() for k, v in rows.items()} == {int(k): v for k, v in MEANINGS.items()}
    assert set(COMMAND_CODES) == set(COMMANDS)


def test_the_command_line_doc_lists_each_commands_exit_codes() -> None:
    doc = (REPO / "docs" / "command-line.md").read_text(encoding="utf-8")
    rows = dict(re.findall(r"^\| `([a-z-]+)` \| ([0-9, ]+) \|$", doc, re.MULTILINE))
    assert {name: [int(c) for c in codes.split(",")] for name, codes in rows.items()} == {
        name: command_codes(name) for name in COMMANDS}


def test_the_commands_doc_test_flag_table_is_the_parser() -> None:
    """Every flag docs/commands.md's ``edc-bench test`` table names exists, and every visible flag of the command is
    there."""
    readme = (REPO / "docs" / "commands.md").read_text(encoding="utf-8")
    start = readme.index("\n|", readme.index("`edc-bench test` flags:"))
    table = readme[start:readme.index("\n\n", start)]
    documented = set(re.findall(r"`(--[a-z0-9-]+)", table))
    parser = build_parser()
    test = parser._subparsers._group_actions[0].choices["test"]
    visible = {option for action in test._actions if action.help != "==SUPPRESS=="
               for option in action.option_strings if option.startswith("--") and option != "--help"}
    assert documented == visible


def test_the_same_thing_has_the_same_flag_everywhere() -> None:
    """``--db`` for the history, ``--valve-id`` for the valve, ``--seed`` a seed; old spellings hidden."""
    parser = build_parser()
    commands = parser._subparsers._group_actions[0].choices
    for name, command in commands.items():
        visible = {o: a for a in command._actions if a.help != "==SUPPRESS==" for o in a.option_strings}
        assert "--history-db" not in visible, name
        if "--valve" in visible:
            assert "SPEC" in (visible["--valve"].metavar or ""), f"{name}: --valve is a simulated valve's spec"
        if "--out" in visible:
            assert visible["--out"].metavar == "DIR", f"{name}: --out is a folder"
    assert "--valve-id" in {o for a in commands["history"]._actions for o in a.option_strings}


# -- what is accepted is kept intact and never crashes what reads it later -----------------------------------------

#: An odd but valid valve id at the length limit: rich markup, XML, quotes, a slash, a backslash, an umlaut, spaces,
#: and what matplotlib would read as a formula it cannot parse (drawn as typed in the record's figure and report).
ODD_ID = ('V[/b] <&> "ä"/\\ $\\q$ ' + "x" * 100)[:100]


@pytest.fixture()
def real_station(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A fresh working folder and station, nothing tripwired."""
    for name, value in (("EDC_BENCH_DATA_DIR", tmp_path / "data"), ("EDC_BENCH_CACHE_DIR", tmp_path / "cache")):
        monkeypatch.setenv(name, str(value))
    for name in ("EDC_BENCH_HISTORY_URL", "CAN_INTERFACE", "CAN_CHANNEL", "CAN_BITRATE"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_an_odd_valve_id_is_kept_intact_from_the_test_to_the_report(real_station: Path,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    import json

    url = f"sqlite:///{real_station / 'h.sqlite'}"
    code, out, err = run_cli(["test", "--valve-id", ODD_ID, "--duration-s", "15", "--out", "rec", "--db", url,
                              "--json"], capsys)
    assert code == ExitCode.PASS, err
    folder = Path(json.loads(out)["record_dir"])
    assert json.loads((folder / "record.json").read_text(encoding="utf-8"))["valve_id"] == ODD_ID
    # the folder's name is cleaned: letters of any script kept, nothing a file system or a shell would take
    assert re.fullmatch(r"[0-9T]+[+-][0-9]{4}-p-edc-default-[\w.-]+", folder.name) and not set(folder.name) & set("/\\ ;'\"$`")
    steps = {
        "listed": ["history", "--db", url, "--valve-id", ODD_ID],
        "trend": ["history", "--db", url, "--trend", ODD_ID, "--include-simulated", "--plot", "trend.png"],
        "added again": ["history", "--db", f"sqlite:///{real_station / 'rebuilt.sqlite'}", "--add", str(folder)],
        "labelled": ["label", ODD_ID, "--finding", "worn", "--db", url],
        "findings": ["label", "--list", "--db", url],
        "report": ["report", str(folder)],
    }
    for step, argv in steps.items():
        code, out, err = run_cli(argv, capsys)
        assert code == 0 and "Traceback" not in err, (step, out, err)
        if step in ("listed", "findings"):
            assert "V[/b] <&>" in out, (step, out)
        if step == "labelled":
            assert "it labels the test of" in out, out
    code, out, _ = run_cli(["history", "--db", url, "--json"], capsys)
    assert [row["valve_id"] for row in json.loads(out)] == [ODD_ID]


def test_a_test_on_a_bus_without_valve_id_records_no_valve_and_says_so(real_station: Path,
                                                                       capsys: pytest.CaptureFixture[str]) -> None:
    """Not the simulated valve's spec ('new'): the bench cannot know which valve is on a real rig."""
    import json

    # no rig will answer: give up waiting for READY after 0.2 s instead of 3
    (real_station / "quick.toml").write_text(variant_with() + "\n[acceptance]\nready_timeout_s = 0.2\n",
                                             encoding="utf-8")
    code, out, err = run_cli(["test", "--variant", "quick.toml", "--interface", "virtual", "--channel",
                              "edc-bench-nobody", "--out", "rec", "--no-history", "--json"], capsys)
    assert code == ExitCode.INVALID, err  # no rig answers on that channel: not READY
    assert "no --valve-id" in err and "--valve-id ID" in err
    folder = Path(json.loads(out)["record_dir"])
    assert json.loads((folder / "record.json").read_text(encoding="utf-8"))["valve_id"] == ""
    assert "new" not in folder.name.split("-bad-")[-1]
