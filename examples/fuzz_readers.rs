//! A seeded mutation fuzzer for the mesh readers (`parse_ply` ASCII and binary, `parse_obj`)
//! that runs on stable Rust with no tool beyond cargo (docs/fuzzing.md).
//!
//! ```text
//! cargo run --profile ci --example fuzz_readers -- --reader obj --seconds 900 --seed 1
//! ```
//!
//! Each execution takes an input of the corpus (`tests/fuzz/corpus/<reader>/`), applies 1 to 8
//! random mutations (bit flips, byte and block edits, splices with another input, numbers
//! replaced by hostile ones: huge counts and indices, negative, NaN, 2³², ...; for OBJ and
//! ASCII PLY also whole hostile lines), and parses it. An input whose outcome is new (the
//! error message with its digits removed, or the shape of a success) joins the in-memory
//! corpus, so the run explores further from the inputs that reach new code. A run is failed
//! by:
//! - a panic (caught; its message is the crash),
//! - an allocation above 1 GiB, or more than 1 GiB alive at once (the counting global
//!   allocator below refuses it and records it; an infallible allocation then aborts),
//! - an abort or a signal (the worker process dies: `--supervise`, the default of the binary,
//!   reruns it and keeps the input),
//! - a success whose mesh is inconsistent (a face index out of range, a normal or color count
//!   that differs from the vertex count).
//!
//! Crashing inputs are written to `--crashes DIR` (default `target/fuzz-crashes/<reader>`);
//! copy them to `tests/fuzz/regressions/` and they are replayed by `cargo test`
//! (tests/fuzz_readers.rs). The last line printed is the run's record.

use std::alloc::{GlobalAlloc, Layout, System};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

// ---------------------------------------------------------------------------------------------
// The counting allocator
// ---------------------------------------------------------------------------------------------

/// The most bytes one allocation, or all live allocations together, may take.
pub const ALLOCATION_LIMIT: usize = 1 << 30;

/// A global allocator that counts live bytes and refuses (returns null for) any request that
/// would take one allocation or the total above [`ALLOCATION_LIMIT`], recording it.
pub struct CountingAlloc;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);
static LARGEST: AtomicUsize = AtomicUsize::new(0);
static REFUSED: AtomicUsize = AtomicUsize::new(0);

impl CountingAlloc {
    fn admit(size: usize) -> bool {
        // An oversized request is refused before it touches the live count, which other
        // threads read: counting it even for an instant would refuse their small requests.
        if size > ALLOCATION_LIMIT {
            REFUSED.fetch_max(size, Ordering::Relaxed);
            return false;
        }
        let live = LIVE.fetch_add(size, Ordering::Relaxed) + size;
        if live > ALLOCATION_LIMIT {
            LIVE.fetch_sub(size, Ordering::Relaxed);
            REFUSED.fetch_max(size, Ordering::Relaxed);
            return false;
        }
        PEAK.fetch_max(live, Ordering::Relaxed);
        LARGEST.fetch_max(size, Ordering::Relaxed);
        true
    }
}

// SAFETY: every method forwards to `System` with the caller's layout (and pointer, for
// `dealloc` and `realloc`), which upholds `GlobalAlloc`'s contract; the counters are plain
// atomics, and a refused request returns null, which the contract allows.
unsafe impl GlobalAlloc for CountingAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if !Self::admit(layout.size()) {
            return std::ptr::null_mut();
        }
        // SAFETY: forwarded with the caller's (valid, non-zero-size) layout.
        let p = unsafe { System.alloc(layout) };
        if p.is_null() {
            LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        }
        p
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if !Self::admit(layout.size()) {
            return std::ptr::null_mut();
        }
        // SAFETY: as `alloc`.
        let p = unsafe { System.alloc_zeroed(layout) };
        if p.is_null() {
            LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        }
        p
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        // SAFETY: `ptr` was allocated by `System` with `layout` (through this allocator).
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let old = layout.size();
        if new_size > ALLOCATION_LIMIT {
            REFUSED.fetch_max(new_size, Ordering::Relaxed);
            return std::ptr::null_mut();
        }
        if new_size > old && !Self::admit(new_size - old) {
            return std::ptr::null_mut();
        }
        LARGEST.fetch_max(new_size, Ordering::Relaxed);
        // SAFETY: `ptr` was allocated by `System` with `layout`; `new_size` is non-zero.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if p.is_null() {
            if new_size > old {
                LIVE.fetch_sub(new_size - old, Ordering::Relaxed);
            }
        } else if new_size < old {
            LIVE.fetch_sub(old - new_size, Ordering::Relaxed);
        }
        p
    }
}

#[global_allocator]
static GLOBAL: CountingAlloc = CountingAlloc;

/// Live bytes now.
pub fn live_bytes() -> usize {
    LIVE.load(Ordering::Relaxed)
}

/// Resets the peak to the live bytes now; returns the peak before.
pub fn reset_peak() -> usize {
    PEAK.swap(live_bytes(), Ordering::Relaxed)
}

/// The largest request refused since the last call (0: none), reset to 0.
pub fn take_refused() -> usize {
    REFUSED.swap(0, Ordering::Relaxed)
}

// ---------------------------------------------------------------------------------------------
// Readers, inputs and mutations
// ---------------------------------------------------------------------------------------------

/// The readers fuzzed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reader {
    /// `parse_ply` on ASCII files.
    PlyAscii,
    /// `parse_ply` on binary (little and big endian) files.
    PlyBinary,
    /// `parse_obj`.
    Obj,
}

impl Reader {
    /// Every reader.
    pub const ALL: [Reader; 3] = [Reader::PlyAscii, Reader::PlyBinary, Reader::Obj];

    /// The name used on the command line and as the corpus folder.
    pub fn name(self) -> &'static str {
        match self {
            Self::PlyAscii => "ply-ascii",
            Self::PlyBinary => "ply-binary",
            Self::Obj => "obj",
        }
    }

    fn from_name(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|r| r.name() == s)
    }

    /// Parses `data` with this reader.
    pub fn parse(self, data: &[u8]) -> foldmatch::Result<foldmatch::io::MeshData> {
        match self {
            Self::PlyAscii | Self::PlyBinary => foldmatch::io::parse_ply(data, "fuzz.ply"),
            Self::Obj => foldmatch::io::parse_obj(data, "fuzz.obj"),
        }
    }

    fn text(self) -> bool {
        self != Self::PlyBinary
    }
}

/// The committed seed corpus of a reader: `tests/fuzz/corpus/<reader>/*`, sorted by name.
pub fn load_corpus(dir: &Path) -> Vec<Vec<u8>> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|d| d.filter_map(|e| e.ok()).map(|e| e.path()).collect())
        .unwrap_or_default();
    paths.sort();
    paths
        .into_iter()
        .filter(|p| p.is_file())
        .filter_map(|p| std::fs::read(p).ok())
        .collect()
}

/// SplitMix64: small, seedable, good enough to pick mutations.
pub struct Rng(u64);

impl Rng {
    /// A generator from a seed.
    pub fn new(seed: u64) -> Self {
        Self(seed ^ 0x9E37_79B9_7F4A_7C15)
    }
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: usize) -> usize {
        if n == 0 {
            0
        } else {
            (self.next() % n as u64) as usize
        }
    }
    fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
}

/// Numbers that break naive readers: counts and indices at type boundaries, negative,
/// non-finite, non-integer.
const HOSTILE_NUMBERS: &[&str] = &[
    "0",
    "-1",
    "1",
    "2",
    "3",
    "255",
    "256",
    "65535",
    "65536",
    "2147483647",
    "2147483648",
    "-2147483648",
    "4294967295",
    "4294967296",
    "1000000000",
    "4000000000",
    "9223372036854775807",
    "-9223372036854775808",
    "18446744073709551616",
    "1e308",
    "1e309",
    "-1e309",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "3.5",
    "1e-320",
    "0x10",
    "",
];

/// Whole lines inserted into text inputs.
const HOSTILE_LINES: &[&str] = &[
    "f 1000000000//1 2//1 3//1",
    "f 1000000000/1/1 2/1/1 3/1/1",
    "f 4000000000//1 2//1 3//1",
    "f -1000000000 1 2",
    "f 1 2",
    "f",
    "f 1//1000000000 2//1 3//1",
    "f 1/2/3/4 2 3",
    "vn 0 0 1",
    "vt 0 0",
    "v 1 2",
    "v nan inf -inf",
    "v 1e309 0 0",
    "\\",
    "element vertex 1000000000",
    "element face 4294967295",
    "element vertex -1",
    "property list uint int vertex_indices",
    "property list uchar float vertex_indices",
    "property list int int x",
    "property double x",
    "format binary_little_endian 1.0",
    "format binary_big_endian 1.0",
    "format ascii 1.0",
    "end_header",
    "4294967295 0 1 2",
    "0",
    "2 0 1",
    "3 0 1 1000000000",
    "comment \u{0}\u{ff}",
];

/// Integers written into binary inputs (little or big endian, 1 to 8 bytes).
const HOSTILE_INTS: &[u64] = &[
    0,
    1,
    2,
    3,
    0x7F,
    0x80,
    0xFF,
    0x7FFF,
    0xFFFF,
    0x7FFF_FFFF,
    0x8000_0000,
    0xFFFF_FFFF,
    1_000_000_000,
    u64::MAX,
    0x7FF0_0000_0000_0000, // +inf as f64
    0x7FF8_0000_0000_0000, // NaN as f64
];

/// The byte ranges of ASCII numbers (digits, signs, dots, letters of nan/inf/e) in `data`.
fn number_spans(data: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut i = 0;
    while i < data.len() {
        if data[i].is_ascii_digit() || data[i] == b'-' {
            let start = i;
            while i < data.len()
                && (data[i].is_ascii_alphanumeric() || matches!(data[i], b'-' | b'+' | b'.'))
            {
                i += 1;
            }
            spans.push((start, i));
        } else {
            i += 1;
        }
    }
    spans
}

/// Applies one random mutation to `data` (never longer than `max_len`).
fn mutate_once(
    data: &mut Vec<u8>,
    corpus: &[Vec<u8>],
    reader: Reader,
    rng: &mut Rng,
    max_len: usize,
) {
    let len = data.len();
    match rng.below(11) {
        0 if len > 0 => {
            let i = rng.below(len);
            data[i] ^= 1 << rng.below(8);
        }
        1 if len > 0 => {
            let i = rng.below(len);
            data[i] = rng.next() as u8;
        }
        2 => {
            let i = rng.below(len + 1);
            data.insert(i, *rng.pick(b"0123456789 -\n/\\#.e\0\xff\r\t"));
        }
        3 if len > 1 => {
            let i = rng.below(len);
            let n = 1 + rng.below((len - i).min(64));
            data.drain(i..i + n);
        }
        4 if len > 1 => {
            // Duplicate a block.
            let i = rng.below(len);
            let n = 1 + rng.below((len - i).min(256));
            let block: Vec<u8> = data[i..i + n].to_vec();
            let at = rng.below(len + 1);
            data.splice(at..at, block);
        }
        5 if !corpus.is_empty() => {
            // Splice: our head with another input's tail.
            let other = rng.pick(corpus);
            let cut = rng.below(len + 1);
            let from = rng.below(other.len() + 1);
            data.truncate(cut);
            data.extend_from_slice(&other[from..]);
        }
        6 | 7 if reader.text() || rng.below(2) == 0 => {
            // Replace a number (in binary inputs: one of the header's).
            let limit = if reader.text() {
                len
            } else {
                header_end(data).unwrap_or(len)
            };
            let spans = number_spans(&data[..limit]);
            if !spans.is_empty() {
                let (a, b) = *rng.pick(&spans);
                let value = rng.pick(HOSTILE_NUMBERS).as_bytes();
                data.splice(a..b, value.iter().copied());
            }
        }
        8 if reader.text() || rng.below(2) == 0 => {
            // Insert a hostile line at a line start (in binary inputs: within the header).
            let limit = if reader.text() {
                len
            } else {
                header_end(data).unwrap_or(len)
            };
            let starts: Vec<usize> = std::iter::once(0)
                .chain((0..limit).filter(|&i| data[i] == b'\n').map(|i| i + 1))
                .collect();
            let at = *rng.pick(&starts);
            let mut line = rng.pick(HOSTILE_LINES).as_bytes().to_vec();
            line.push(b'\n');
            data.splice(at..at, line);
        }
        6..=9 if len > 0 => {
            // Write a hostile integer into the payload, 1, 2, 4 or 8 bytes, either endian.
            let start = if reader.text() {
                0
            } else {
                header_end(data).unwrap_or(0)
            };
            if start < len {
                let width = *rng.pick(&[1usize, 2, 4, 8]);
                let at = start + rng.below(len - start);
                let v = *rng.pick(HOSTILE_INTS);
                let bytes = if rng.below(2) == 0 {
                    v.to_le_bytes()
                } else {
                    v.to_be_bytes()
                };
                let bytes = if bytes[0] == 0 && width < 8 {
                    &bytes[8 - width..]
                } else {
                    &bytes[..width]
                };
                for (k, &b) in bytes.iter().enumerate() {
                    if at + k < len {
                        data[at + k] = b;
                    }
                }
            }
        }
        _ if len > 0 => {
            // Truncate.
            data.truncate(rng.below(len));
        }
        _ => {
            let other = rng.pick(corpus);
            data.extend_from_slice(other);
        }
    }
    data.truncate(max_len);
}

/// Where a PLY header ends (just after `end_header\n`).
fn header_end(data: &[u8]) -> Option<usize> {
    let tag = b"end_header";
    data.windows(tag.len())
        .position(|w| w == tag)
        .map(|i| (i + tag.len() + 1).min(data.len()))
}

/// What one execution came to.
#[derive(Debug)]
pub enum Verdict {
    /// A mesh (consistent) or a typed error: the outcome's class (digits removed).
    Clean(String),
    /// A bug: why.
    Crash(String),
}

thread_local! {
    static PANIC_MESSAGE: std::cell::RefCell<Option<String>> = const { std::cell::RefCell::new(None) };
}
static HOOK: std::sync::Once = std::sync::Once::new();
static QUIET_PANICS: AtomicBool = AtomicBool::new(true);

/// Runs one input through `reader`, checking every property of a clean outcome.
pub fn execute(reader: Reader, data: &[u8]) -> Verdict {
    HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            let message = info.to_string();
            PANIC_MESSAGE.with(|m| *m.borrow_mut() = Some(message));
            if !QUIET_PANICS.load(Ordering::Relaxed) {
                previous(info);
            }
        }));
    });
    take_refused();
    let outcome = std::panic::catch_unwind(|| reader.parse(data));
    let refused = take_refused();
    if refused > 0 {
        return Verdict::Crash(format!(
            "allocation of {refused} bytes refused (limit {ALLOCATION_LIMIT})"
        ));
    }
    match outcome {
        Err(_) => {
            let message = PANIC_MESSAGE
                .with(|m| m.borrow_mut().take())
                .unwrap_or_else(|| "panic".into());
            Verdict::Crash(format!("panic: {message}"))
        }
        Ok(Ok(mesh)) => match mesh.check_consistency() {
            Ok(()) => Verdict::Clean(format!(
                "ok v{} f{} n{} c{}",
                mesh.vertices.len().min(3),
                mesh.faces.len().min(3),
                mesh.normals.is_some(),
                mesh.colors.is_some()
            )),
            Err(e) => Verdict::Crash(format!("inconsistent mesh: {e}")),
        },
        Ok(Err(e)) => {
            let text = e.to_string();
            if text.contains("panicked") || text.contains("RUST_BACKTRACE") {
                return Verdict::Crash(format!("panic text in an error: {text}"));
            }
            // The class of the error: its lowercase words up to the first quoted value (element
            // and property names, which mutations change, mostly are not).
            let head: String = text
                .chars()
                .take_while(|&c| c != '\'' && c != '"')
                .collect();
            let class: Vec<&str> = head
                .split(|c: char| !c.is_ascii_alphabetic())
                .filter(|w| w.len() >= 3 && w.bytes().all(|b| b.is_ascii_lowercase()))
                .collect();
            let class = class.join(" ");
            Verdict::Clean(class)
        }
    }
}

/// One fuzzing run's settings.
#[derive(Clone, Debug)]
pub struct Config {
    /// The reader.
    pub reader: Reader,
    /// How long to run.
    pub duration: Duration,
    /// Stop after this many executions (0: no limit).
    pub max_runs: u64,
    /// The seed of the mutations.
    pub seed: u64,
    /// The seed corpus.
    pub corpus: Vec<Vec<u8>>,
    /// The longest input generated.
    pub max_len: usize,
    /// Where crashing inputs are written (`None`: nowhere).
    pub crashes: Option<PathBuf>,
    /// A file that holds the input being run (length-prefixed), so that a supervisor can keep
    /// the input of an abort.
    pub current: Option<PathBuf>,
}

/// What a run did.
#[derive(Clone, Debug, Default)]
pub struct Summary {
    /// Executions.
    pub runs: u64,
    /// Corpus size at the start and at the end (the inputs with a new outcome join it).
    pub corpus_start: usize,
    /// Corpus size at the end.
    pub corpus_end: usize,
    /// Distinct outcome classes seen.
    pub outcomes: usize,
    /// Crashes: (why, input).
    pub crashes: Vec<(String, Vec<u8>)>,
    /// The most bytes alive at once during an execution (above what was alive before it).
    pub peak_bytes: usize,
    /// The slowest execution.
    pub slowest: Duration,
}

/// Runs the fuzzer in this process.
pub fn run(cfg: &Config) -> Summary {
    let mut rng = Rng::new(cfg.seed);
    let mut corpus = cfg.corpus.clone();
    if corpus.is_empty() {
        corpus.push(Vec::new());
    }
    let mut seen = std::collections::HashSet::new();
    let mut summary = Summary {
        corpus_start: corpus.len(),
        ..Default::default()
    };
    let mut current = cfg
        .current
        .as_ref()
        .and_then(|p| std::fs::File::create(p).ok());
    let started = Instant::now();
    let mut input = Vec::new();
    // The seeds themselves first, then mutations.
    let mut k = 0usize;
    loop {
        if summary.runs.is_multiple_of(64)
            && started.elapsed() >= cfg.duration
            && k >= cfg.corpus.len()
        {
            break;
        }
        if cfg.max_runs > 0 && summary.runs >= cfg.max_runs {
            break;
        }
        input.clear();
        if k < cfg.corpus.len() {
            input.extend_from_slice(&cfg.corpus[k]);
            k += 1;
        } else {
            input.extend_from_slice(&corpus[rng.below(corpus.len())]);
            for _ in 0..1 + rng.below(8) {
                mutate_once(&mut input, &corpus, cfg.reader, &mut rng, cfg.max_len);
            }
        }
        if let Some(f) = current.as_mut() {
            write_current(f, &input);
        }
        let base = live_bytes();
        reset_peak();
        let t = Instant::now();
        let verdict = execute(cfg.reader, &input);
        summary.slowest = summary.slowest.max(t.elapsed());
        summary.peak_bytes = summary.peak_bytes.max(reset_peak().saturating_sub(base));
        summary.runs += 1;
        match verdict {
            Verdict::Clean(class) => {
                if std::env::var_os("FUZZ_SHOW_OUTCOMES").is_some() && !seen.contains(&class) {
                    eprintln!("new outcome: {class}");
                }
                if seen.insert(class) && corpus.len() < 4096 {
                    corpus.push(input.clone());
                }
            }
            Verdict::Crash(why) => {
                if let Some(dir) = &cfg.crashes {
                    let _ = std::fs::create_dir_all(dir);
                    let path = dir.join(format!("crash-{}-{}", cfg.seed, summary.runs));
                    let _ = std::fs::write(&path, &input);
                    eprintln!("crash ({why}): input written to {}", path.display());
                } else {
                    eprintln!("crash ({why})");
                }
                if summary.crashes.len() < 100 {
                    summary.crashes.push((why, input.clone()));
                }
            }
        }
    }
    summary.corpus_end = corpus.len();
    summary.outcomes = seen.len();
    summary
}

/// Stores the input being run (8-byte length, then the bytes) at the start of `f`.
fn write_current(f: &mut std::fs::File, input: &[u8]) {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileExt;
        let mut buf = (input.len() as u64).to_le_bytes().to_vec();
        buf.extend_from_slice(input);
        let _ = f.write_all_at(&buf, 0);
    }
    #[cfg(not(unix))]
    let _ = (f, input);
}

/// Reads what [`write_current`] stored.
fn read_current(path: &Path) -> Option<Vec<u8>> {
    let data = std::fs::read(path).ok()?;
    let n = u64::from_le_bytes(data.get(..8)?.try_into().ok()?) as usize;
    data.get(8..8 + n).map(<[u8]>::to_vec)
}

// ---------------------------------------------------------------------------------------------
// The command line
// ---------------------------------------------------------------------------------------------

fn usage() -> ! {
    eprintln!(
        "usage: fuzz_readers [--reader ply-ascii|ply-binary|obj] [--seconds S] [--runs N] \
         [--seed N] [--corpus DIR] [--crashes DIR] [--max-len BYTES] [--no-supervise]"
    );
    std::process::exit(2)
}

#[allow(dead_code)]
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let mut reader = Reader::Obj;
    let mut seconds = 10.0f64;
    let mut runs = 0u64;
    let mut seed = 1u64;
    let mut corpus_dir: Option<PathBuf> = None;
    let mut crashes: Option<PathBuf> = None;
    let mut max_len = 64 * 1024;
    let mut supervise = true;
    let mut worker_current: Option<PathBuf> = None;
    let mut i = 1;
    while i < args.len() {
        let value = |i: usize| args.get(i + 1).cloned().unwrap_or_else(|| usage());
        match args[i].as_str() {
            "--reader" => reader = Reader::from_name(&value(i)).unwrap_or_else(|| usage()),
            "--seconds" => seconds = value(i).parse().unwrap_or_else(|_| usage()),
            "--runs" => runs = value(i).parse().unwrap_or_else(|_| usage()),
            "--seed" => seed = value(i).parse().unwrap_or_else(|_| usage()),
            "--corpus" => corpus_dir = Some(value(i).into()),
            "--crashes" => crashes = Some(value(i).into()),
            "--max-len" => max_len = value(i).parse().unwrap_or_else(|_| usage()),
            "--no-supervise" => {
                supervise = false;
                i += 1;
                continue;
            }
            "--worker-current" => {
                worker_current = Some(value(i).into());
                supervise = false;
            }
            _ => usage(),
        }
        i += 2;
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let corpus_dir =
        corpus_dir.unwrap_or_else(|| root.join("tests/fuzz/corpus").join(reader.name()));
    let crashes = crashes.unwrap_or_else(|| root.join("target/fuzz-crashes").join(reader.name()));
    if supervise {
        std::process::exit(supervisor(&args, reader, seconds, seed, &crashes));
    }
    let corpus = load_corpus(&corpus_dir);
    let cfg = Config {
        reader,
        duration: Duration::from_secs_f64(seconds),
        max_runs: runs,
        seed,
        corpus,
        max_len,
        crashes: Some(crashes),
        current: worker_current,
    };
    let started = Instant::now();
    let s = run(&cfg);
    println!(
        "record: reader={} seed={} seconds={:.0} runs={} corpus={}->{} outcomes={} crashes={} \
         peak_bytes={} slowest_ms={:.1}",
        reader.name(),
        seed,
        started.elapsed().as_secs_f64(),
        s.runs,
        s.corpus_start,
        s.corpus_end,
        s.outcomes,
        s.crashes.len(),
        s.peak_bytes,
        s.slowest.as_secs_f64() * 1e3
    );
    std::process::exit(if s.crashes.is_empty() { 0 } else { 1 });
}

/// Runs workers (this program with `--worker-current`) until the time is up; a worker that
/// dies (an abort, a signal) has its input kept as a crash, and a new one starts with the
/// next seed. Prints the workers' records and one total record.
fn supervisor(args: &[String], reader: Reader, seconds: f64, seed: u64, crashes: &Path) -> i32 {
    let exe = std::env::current_exe().expect("current exe");
    let started = Instant::now();
    let current = std::env::temp_dir().join(format!("fuzz-current-{}", std::process::id()));
    let mut seed = seed;
    let mut failures = 0;
    let (mut total_runs, mut deaths) = (0u64, 0usize);
    loop {
        let left = seconds - started.elapsed().as_secs_f64();
        if left <= 0.0 {
            break;
        }
        let mut worker_args: Vec<String> = Vec::new();
        let mut i = 1;
        while i < args.len() {
            match args[i].as_str() {
                "--seconds" | "--seed" | "--worker-current" => i += 2,
                "--no-supervise" => i += 1,
                a => {
                    worker_args.push(a.to_string());
                    i += 1;
                }
            }
        }
        let out = std::process::Command::new(&exe)
            .args(&worker_args)
            .args([
                "--seconds",
                &format!("{left:.3}"),
                "--seed",
                &seed.to_string(),
            ])
            .arg("--worker-current")
            .arg(&current)
            .stderr(std::process::Stdio::inherit())
            .output()
            .expect("start a worker");
        let text = String::from_utf8_lossy(&out.stdout);
        print!("{text}");
        if let Some(runs) = text
            .split_whitespace()
            .find_map(|w| w.strip_prefix("runs="))
            .and_then(|r| r.parse::<u64>().ok())
        {
            total_runs += runs;
        }
        match out.status.code() {
            Some(0) => {}
            Some(1) => failures += 1,
            other => {
                deaths += 1;
                failures += 1;
                let input = read_current(&current).unwrap_or_default();
                let _ = std::fs::create_dir_all(crashes);
                let path = crashes.join(format!("abort-{seed}"));
                let _ = std::fs::write(&path, &input);
                eprintln!(
                    "worker died ({other:?}, {}); input written to {}",
                    out.status,
                    path.display()
                );
            }
        }
        seed += 1;
        if out.status.code() == Some(0) || out.status.code() == Some(1) {
            break;
        }
    }
    let _ = std::fs::remove_file(&current);
    println!(
        "total: reader={} seconds={:.0} runs={} worker_deaths={} failed_workers={}",
        reader.name(),
        started.elapsed().as_secs_f64(),
        total_runs,
        deaths,
        failures
    );
    i32::from(failures > 0)
}
