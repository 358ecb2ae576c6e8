"""The archive: every ingested record in Parquet, derived tables beside them, SQL over both.

Modules: :mod:`store` (directory layout, manifest, lock, atomic publish),
:mod:`parts` (partitioned Parquet writing), :mod:`records` (parser chunks ⇄
Arrow), :mod:`ledger` (what was read of which file), :mod:`ingest` (with its steps'
modules ``ingest_*`` and :mod:`whole_files`),
:mod:`derive` (the batch analyses run on the archive's records, with
:mod:`group_run`, :mod:`derive_groups`, :mod:`derive_settings`, :mod:`group_records`), :mod:`views`
(DuckDB, read-only, over :mod:`tables`, with :mod:`duck` and :mod:`partition_filter`), :mod:`query`
(read-only queries on it), :mod:`presets` (named queries), :mod:`history`
(report inputs and replay for a time window).
"""
