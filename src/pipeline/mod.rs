//! Sequences load, repair and the selected stages, writes the artifacts and
//! the report, and reports progress.
