"""Analysis: what finished run directories say.

`summary` (per-seed metrics and the summary table), `aggregate` (runs grouped into curves),
`statistics` (tests and intervals), `claims`, `findings` and `study` (the paper's claims and the
study's questions checked against the data), `report` with `report_figures`, `report_groups` and
`report_tables` (the report command), and `doc_tables` (the generated tables of the documentation).
Reads run directories through `lava_bridge_mj.eval.training`'s run-file readers."""
