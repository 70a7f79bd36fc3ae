//! End-to-end tests of vmt across its crates, run on the scenarios shipped in `scenarios/`.
//! The tests are in `tests/tests/`; this library holds nothing.
