"""Result records: moved to :mod:`repbench.records`; this module re-exports it.

The record format and the reading of records (from a stage store or a folder of JSON records)
live in :mod:`repbench.records`, below both the pipeline that writes records and the analysis
that reads them, so that the analysis needs nothing of ``repbench.pipeline``. Existing imports
from ``repbench.pipeline.records`` keep working: every public name is the same object.
"""

from __future__ import annotations

from repbench.provenance import cpu_model, git_commit, library_versions
from repbench.records import (
    CHECKSUM,
    IDENTITY_PARTS,
    META,
    PLUGIN_PARTS,
    RECORD_FILE,
    RECORD_STAGES,
    RERUN,
    SCHEMA,
    SCHEMA_VERSION,
    file_sha256,
    holds_exported_records,
    identity,
    identity_key,
    inspect_record,
    is_store_root,
    jsonable,
    make_record,
    mixed_encoder_weights,
    plugin_part,
    plugin_version,
    read_record,
    record_checksum,
    store_record_files,
    store_record_problem,
    value_problem,
    versions_of,
    write_record,
)

__all__ = [
    "CHECKSUM", "IDENTITY_PARTS", "META", "PLUGIN_PARTS", "RECORD_FILE", "RECORD_STAGES", "RERUN",
    "SCHEMA", "SCHEMA_VERSION", "cpu_model", "file_sha256", "git_commit",
    "holds_exported_records", "identity", "identity_key", "inspect_record", "is_store_root",
    "jsonable", "library_versions", "make_record", "mixed_encoder_weights", "plugin_part",
    "plugin_version", "read_record", "record_checksum", "store_record_files",
    "store_record_problem", "value_problem", "versions_of", "write_record",
]
