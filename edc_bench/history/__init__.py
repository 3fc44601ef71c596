"""The station's history of bench tests (see :mod:`edc_bench.history.store`)."""

from edc_bench.history.store import Filters, HistoryStore, default_url, index_record_dir

__all__ = ["Filters", "HistoryStore", "default_url", "index_record_dir"]
