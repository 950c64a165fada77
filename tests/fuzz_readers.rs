//! The mesh readers under the fuzz driver (examples/fuzz_readers.rs, docs/fuzzing.md), in this
//! test binary with its counting allocator: a short seeded run per reader (the CI run; the long
//! runs are recorded in docs/fuzzing.md), and every input kept in `tests/fuzz/regressions/`
//! (crashes found by fuzzing and the inputs of issue 31) replayed with a bound on the memory
//! it may take.

#[path = "../examples/fuzz_readers.rs"]
#[allow(dead_code)]
mod driver;

use driver::{execute, live_bytes, load_corpus, reset_peak, run, Config, Reader, Verdict};
use std::path::Path;
use std::sync::{Mutex, MutexGuard};
use std::time::Duration;

/// The counting allocator's live bytes, peak and refusals are process-wide, so tests running
/// side by side would see each other's allocations (a large request admitted in one test
/// leaves too little of the limit for an infallible allocation in another, which aborts the
/// process; a refusal in one would be blamed on another's input). Each test holds this lock
/// for its whole run.
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

fn serial() -> MutexGuard<'static, ()> {
    ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner())
}

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The allocator refuses what a reader must never ask for, and the driver calls it a crash.
#[test]
fn the_driver_catches_large_allocations_and_panics() {
    let _serial = serial();
    let mut v: Vec<u8> = Vec::new();
    assert!(v.try_reserve_exact(driver::ALLOCATION_LIMIT + 1).is_err());
    assert!(driver::take_refused() > driver::ALLOCATION_LIMIT);
    // A clean outcome of a valid file and of a malformed one.
    assert!(matches!(
        execute(Reader::Obj, b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"),
        Verdict::Clean(_)
    ));
    assert!(matches!(
        execute(Reader::Obj, b"f 1 2\n"),
        Verdict::Clean(_)
    ));
}

fn short_run(reader: Reader, seed: u64) {
    let _serial = serial();
    let corpus = load_corpus(&root().join("tests/fuzz/corpus").join(reader.name()));
    assert!(corpus.len() >= 5, "{}: seed corpus missing", reader.name());
    let summary = run(&Config {
        reader,
        duration: Duration::from_millis(1500),
        max_runs: 0,
        seed,
        corpus,
        max_len: 64 * 1024,
        crashes: None,
        current: None,
    });
    assert!(summary.runs > 1000, "{summary:?}");
    let crashes: Vec<&String> = summary.crashes.iter().map(|c| &c.0).collect();
    assert!(crashes.is_empty(), "{}: {crashes:?}", reader.name());
    assert!(summary.outcomes > 10, "{summary:?}");
}

#[test]
fn short_fuzz_ply_ascii() {
    short_run(Reader::PlyAscii, 7);
}

#[test]
fn short_fuzz_ply_binary() {
    short_run(Reader::PlyBinary, 7);
}

#[test]
fn short_fuzz_obj() {
    short_run(Reader::Obj, 7);
}

/// Every kept input: a clean outcome, within 64 bytes of memory per input byte (+ 1 MB).
/// The reader is chosen by the name: `obj-*`, `ply-ascii-*` or `ply-binary-*`.
#[test]
fn regressions_are_clean_and_bounded() {
    let _serial = serial();
    let dir = root().join("tests/fuzz/regressions");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let reader = Reader::ALL
            .into_iter()
            .filter(|r| name.starts_with(&format!("{}-", r.name())))
            .max_by_key(|r| r.name().len())
            .unwrap_or_else(|| panic!("{name}: no reader prefix"));
        let data = std::fs::read(&path).unwrap();
        let base = live_bytes();
        reset_peak();
        let verdict = execute(reader, &data);
        let peak = reset_peak().saturating_sub(base);
        assert!(matches!(verdict, Verdict::Clean(_)), "{name}: {verdict:?}");
        assert!(
            peak <= 64 * data.len() + (1 << 20),
            "{name}: {peak} bytes for a {}-byte input",
            data.len()
        );
        n += 1;
    }
    assert!(n >= 8, "{n} regression inputs");
}
