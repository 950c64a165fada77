//! Snapshot tests of the `foldmatch` command line (trycmd): every `--help` page and the usage
//! errors that need no input file, in `tests/cmd/*.toml` with their `.stdout` / `.stderr`.
//! Regenerate after a deliberate change with `TRYCMD=overwrite cargo test --features cli
//! --test cli_snapshots`, then put back the `...` line that stands for the flags generated
//! from newer `FitParams` fields (at the end of the "Fit parameters" section of the
//! fit/batch/sequence/demo help pages): those follow the core and are checked by the unit tests
//! of `src/cli/args.rs` instead.

#[test]
fn cli_snapshots() {
    trycmd::TestCases::new()
        .register_bin(
            "foldmatch",
            std::path::Path::new(env!("CARGO_BIN_EXE_foldmatch")),
        )
        .env("FOLDMATCH_NO_PROGRESS", "1")
        .env("COLUMNS", "100")
        .case("tests/cmd/*.toml");
}
