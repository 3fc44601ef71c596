"""Test records: per-tick trace, raw CAN log, record.json, report figure."""
