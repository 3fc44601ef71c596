"""Pump variant configuration (TOML files validated by pydantic)."""

from edc_bench.config.loader import (
    DEFAULT_VARIANT,
    available_variants,
    load_variant,
    parse_variant,
    variant_dirs,
    with_changes,
)
from edc_bench.config.models import Variant

__all__ = ["DEFAULT_VARIANT", "Variant", "available_variants", "load_variant", "parse_variant", "variant_dirs",
           "with_changes"]
