//! The documented limits on sizes and counts that come from input (docs/cli.md, "Limits"), in
//! one place. Every size a file header, an index or a parameter announces is checked against
//! what the input can hold or against one of these limits *before* anything is allocated, and
//! the allocations that can still fail (a file whose size fits the limits on a machine with
//! less memory) go through [`try_vec`] / [`push`], which turn a failed allocation into
//! [`FoldMatchError::OutOfMemory`] instead of aborting the process.

use crate::error::{FoldMatchError, Result};

/// The most iterations a fit may run (ξ): 10⁶ (a fit of 100 to 150 is typical; the history
/// of 10⁶ iterations is 32 MB).
pub const MAX_ITERATIONS: usize = 1_000_000;

/// The largest value of the unbounded positive real parameters (gravity, softening,
/// time_step, masses, two_way, anneal, tolerance, ...): 10⁶. They act in the normalized frame
/// (the target's bounding-box diagonal is 1), where the defaults are between 0.006 and 4.5; a
/// value of 10⁶ already moves the template millions of diagonals in one step.
pub const MAX_PARAMETER: f64 = 1.0e6;

/// The most bytes read from a FIFO (a pipe given as a file name, e.g. `/dev/stdin`), whose
/// size is not known in advance: 1 GiB. Devices (`/dev/zero`, `/dev/urandom`) and sockets are
/// refused; regular files are read whole (their size is known and reserved up front).
pub const MAX_STREAM_BYTES: u64 = 1 << 30;

/// The largest parameters file (`--params FILE.json`): 16 MiB.
pub const MAX_PARAMS_FILE_BYTES: u64 = 16 << 20;

/// The most vertices per side of the generated folded sheet (`folded_sheet`, `demo --nx`).
pub const MAX_SHEET_SIDE: usize = 10_000;

/// The most vertices of the generated folded sheet (nx · ny): 10⁷.
pub const MAX_SHEET_VERTICES: usize = 10_000_000;

/// The most scan points of the generated folded sheet (`scan_points`): 10⁷ (240 MB).
pub const MAX_SHEET_SCAN_POINTS: usize = 10_000_000;

/// The most vertices a mesh may have: vertex indices are 32-bit (`u32`), and one value is
/// kept as a marker.
pub const MAX_VERTICES: usize = u32::MAX as usize - 1;

/// The largest K of the target neighborhoods (`k_max`): 1,024 (the defaults are 32 and the
/// paper's 64; the neighbor lists take M·K entries).
pub const MAX_K: usize = 1024;

/// The most bytes the kept snapshots of a fit (`snapshot_every`) may take: 4 GiB.
pub const MAX_SNAPSHOT_BYTES: usize = 4 << 30;

/// Checks that the snapshots `params` asks for, of a template of `m` vertices, fit in
/// [`MAX_SNAPSHOT_BYTES`] (one copy of the vertices every `snapshot_every` iterations).
pub fn check_snapshots(params: &crate::FitParams, m: usize) -> Result<()> {
    if params.snapshot_every == 0 {
        return Ok(());
    }
    let count = params.iterations / params.snapshot_every + 1;
    let bytes = count.saturating_mul(m).saturating_mul(24);
    if bytes > MAX_SNAPSHOT_BYTES {
        return Err(FoldMatchError::parameter(
            "snapshot_every",
            params.snapshot_every,
            &format!(
                "{count} snapshots of {m} vertices take {bytes} bytes, more than the limit of \
                 {MAX_SNAPSHOT_BYTES}: keep fewer"
            ),
        ));
    }
    Ok(())
}

/// The most n-rings of a neighborhood (`rings`, `n_rings`): 8, as [`crate::FitParams`].
pub const MAX_RINGS: usize = 8;

/// The machine's hardware threads (1 when unknown).
pub fn available_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// The most worker threads a fit may use: 4 per hardware thread of the machine (at least 4);
/// more only slows it down (each thread is scheduled, few run).
pub fn max_threads() -> usize {
    (4 * available_threads()).max(4)
}

/// Checks a thread count (`--threads`, `threads=`): 1 ..= [`max_threads`].
pub fn check_threads(name: &str, threads: usize) -> Result<usize> {
    let most = max_threads();
    if (1..=most).contains(&threads) {
        Ok(threads)
    } else {
        Err(FoldMatchError::parameter(
            name,
            threads,
            &format!(
                "must be in 1..={most} (4 per hardware thread; this machine has {})",
                available_threads()
            ),
        ))
    }
}

/// A vector with room for `n` items, or [`FoldMatchError::OutOfMemory`] naming `what`.
pub fn try_vec<T>(n: usize, what: &str) -> Result<Vec<T>> {
    let mut v = Vec::new();
    reserve(&mut v, n, what)?;
    Ok(v)
}

/// Reserves room for `extra` more items, or returns [`FoldMatchError::OutOfMemory`].
pub fn reserve<T>(v: &mut Vec<T>, extra: usize, what: &str) -> Result<()> {
    v.try_reserve_exact(extra).map_err(|_| {
        FoldMatchError::out_of_memory(what, extra.saturating_mul(std::mem::size_of::<T>()))
    })
}

/// Pushes `item`, growing the vector (doubling) with a fallible allocation.
#[inline]
pub fn push<T>(v: &mut Vec<T>, item: T, what: &str) -> Result<()> {
    if v.len() == v.capacity() {
        grow(v, what)?;
    }
    v.push(item);
    Ok(())
}

#[cold]
fn grow<T>(v: &mut Vec<T>, what: &str) -> Result<()> {
    let extra = v.len().max(64);
    v.try_reserve(extra).map_err(|_| {
        FoldMatchError::out_of_memory(
            what,
            (v.len() + extra).saturating_mul(std::mem::size_of::<T>()),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn impossible_reservations_are_typed_errors() {
        let err = try_vec::<[f64; 3]>(usize::MAX / 2, "vertices").unwrap_err();
        assert!(matches!(err, FoldMatchError::OutOfMemory { .. }), "{err:?}");
        assert!(err.to_string().contains("vertices"), "{err}");
        let mut v: Vec<u8> = Vec::new();
        for i in 0..1000u32 {
            push(&mut v, i as u8, "bytes").unwrap();
        }
        assert_eq!(v.len(), 1000);
        assert_eq!(v[999], (999 % 256) as u8);
    }

    /// Issue 31, items 3 and 8: iterations = 0 is refused by validation (it used to panic
    /// with "min > max" inside the fit), as are 10⁹ iterations (32 GB of history up front)
    /// and huge finite reals; the messages name the parameter and its value only.
    #[test]
    fn parameters_are_validated_against_their_domain() {
        use crate::FitParams;
        let check = |p: FitParams, expected: &str| {
            let err = p.validate().unwrap_err().to_string();
            assert!(err.starts_with(expected), "{err}");
        };
        check(
            FitParams {
                iterations: 0,
                ..FitParams::default()
            },
            "parameter iterations = 0: must be in 1..=1000000",
        );
        check(
            FitParams {
                iterations: 1_000_000_000,
                ..FitParams::default()
            },
            "parameter iterations = 1000000000:",
        );
        let mut p = FitParams::default();
        p.model.nbody.gravity = 1e300;
        check(p, "parameter gravity = 1e300: must be in (0, 1e6]");
        check(
            {
                let mut p = FitParams::default();
                p.model.rho = f64::NAN; // a nested field: no struct update
                p
            },
            "parameter rho = NaN:",
        );
        assert!(FitParams {
            iterations: MAX_ITERATIONS,
            ..FitParams::default()
        }
        .validate()
        .is_ok());
        // From JSON: the key alone is named, never the whole object.
        for (json, expected) in [
            (
                r#"{"rho": "NaN", "psi": 0.1}"#,
                "parameter rho = NaN: must be a finite number",
            ),
            (
                r#"{"rho": "-inf"}"#,
                "parameter rho = -inf: must be a finite number",
            ),
            (
                r#"{"rho": null}"#,
                "parameter rho = null: must be a finite number",
            ),
            (
                r#"{"iterations": -1}"#,
                "parameter iterations = -1: invalid value",
            ),
            (
                r#"{"iterations": 0}"#,
                "parameter iterations = 0: must be in 1..=",
            ),
            (r#"{"rings": "two"}"#, "parameter rings = two: invalid type"),
        ] {
            let err = FitParams::from_json(json).unwrap_err().to_string();
            assert!(err.starts_with(expected), "{json}: {err}");
            assert!(!err.contains('{'), "{err}");
        }
        // And the fit itself refuses them before doing anything (no panic).
        let tri = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let p = FitParams {
            iterations: 0,
            ..FitParams::default()
        };
        let err = crate::fit::fit(&tri, &[[0, 1, 2]], &tri, None, &p, &mut |_| true);
        assert!(matches!(err, Err(FoldMatchError::Parameter { .. })));
    }

    #[test]
    fn thread_counts_are_bounded_by_the_machine() {
        assert_eq!(check_threads("threads", 1).unwrap(), 1);
        assert!(check_threads("threads", max_threads()).is_ok());
        for bad in [0, max_threads() + 1, 65_535] {
            let err = check_threads("threads", bad).unwrap_err().to_string();
            assert!(
                err.starts_with(&format!("parameter threads = {bad}:")),
                "{err}"
            );
            assert!(err.contains("hardware thread"), "{err}");
        }
    }
}
