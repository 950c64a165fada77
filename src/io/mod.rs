//! Mesh and point-cloud files: PLY (ASCII, binary little and big endian) and Wavefront OBJ,
//! read into one plain [`MeshData`] value and written back atomically; plus the viridis
//! colormap used to paint the wrinkle-vector field onto a mesh.
//!
//! # Reading
//! [`read_mesh`] dispatches on the extension (`.ply` / `.obj`, any case); [`read_ply`] and
//! [`read_obj`] read one format; [`parse_ply`] and [`parse_obj`] parse bytes already in memory
//! (tests, network buffers, Python `bytes`); [`read_ply_property`] also reads one more
//! per-vertex scalar property of a PLY (a segmenter's labels, a scanner's confidence), and
//! [`read_npy`] reads a one-dimensional NumPy `.npy` array (per-point scan weights). Every
//! error is a [`FoldMatchError::Format`] that names the file, the 1-based line (header and ASCII payload lines; 0 inside binary data) and
//! the reason, or a [`FoldMatchError::Io`] when the file cannot be read at all. NaN and infinite
//! coordinates are *not* I/O errors: they are read as they are, and the fit's input validation
//! reports them.
//!
//! # Writing
//! [`write_ply`], [`write_obj`] and [`write_mesh`] never leave a partial file at the target
//! path: they write a temporary file `.NAME.tmp.PID.N` in the target's directory, flush and
//! `fsync` it, then rename it over the target (atomic on POSIX file systems, and a replacing
//! rename on Windows). On any failure the temporary file is removed and the target is left as
//! it was. Extra per-vertex columns (the wrinkle-vector field and its magnitude) are written to
//! PLY as `property double NAME` ([`VertexProperty`]), colors as `uchar red/green/blue`.
//!
//! # Why hand-written parsers
//! The crates that exist were read (`ply-rs` 0.1.3 and `tobj` 4.0.5) and rejected for reasons
//! that matter to this project; the parsers here are small, have no dependency, and are
//! tested against files written by `trimesh` (when Python and trimesh are installed).
//! - **`ply-rs` 0.1.3** (last release 2020) stores every element as a
//!   `LinkedHashMap<String, Property>` unless one implements its `PropertyAccess` trait by hand,
//!   which costs hundreds of bytes per vertex on a million-point scan; it cannot compare a
//!   header's element counts with the data that is actually there (it only fails with an
//!   `UnexpectedEof` after reading as far as it can), so it cannot give the "header announces N
//!   vertices but the file holds at most M" diagnosis the spec asks for; its errors carry
//!   neither a file name nor (in binary payloads) a position we could map; and it pulls `peg`
//!   0.6 plus a `skeptic` build-dependency tree into every build.
//! - **`tobj` 4.0.5** re-indexes vertices per object/group (`o`/`g`), so vertex order and count
//!   are not preserved (unreferenced vertices vanish: a point cloud OBJ loads empty, and a
//!   template's vertex order, which ground-truth correspondences rely on, changes); it divides
//!   `x y z` by an optional `w` instead of ignoring it; its `LoadError` has no line number; and
//!   it reads `f32` unless a crate-wide feature is switched.
//!
//! The PLY reader checks every element count of the header against the bytes that follow
//! before it reserves anything: each record needs at least its fixed size in binary, and at
//! least two bytes per value (one character and one separator) in ASCII, so a header
//! announcing 10⁹ vertices in a 1 KB file is rejected at once, and no allocation is ever larger
//! than a small multiple of the file's size.

mod colormap;
mod fitted;
mod landmarks;
mod npy;
mod obj;
mod ply;

pub use colormap::{colormap_viridis, robust_range, wrinkle_colors};
pub use fitted::fitted_mesh;
pub use landmarks::{
    parse_csv as parse_landmarks_csv, parse_json as parse_landmarks_json, read_landmarks,
    LandmarkFile,
};
pub use npy::{parse_npy, read_npy, write_npy_mask};
pub use obj::{parse_obj, read_obj, write_obj, write_obj_to};
pub use ply::{
    parse_ply, parse_ply_property, read_ply, read_ply_property, write_ply, write_ply_to,
    write_ply_with_encoding, PlyEncoding,
};

use crate::error::{FoldMatchError, Result};
use std::fs::{self, File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

/// A triangle mesh or a point cloud as read from / written to a file.
///
/// `faces` is empty for a point cloud. `normals` and `colors`, when present, have one entry per
/// vertex. Polygons of the file are fan-triangulated (`(a, b, c, d)` → `(a, b, c)`, `(a, c, d)`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshData {
    /// Vertex positions, `(M, 3)`.
    pub vertices: Vec<[f64; 3]>,
    /// Triangles as 0-based vertex indices, `(T, 3)`; empty for a point cloud.
    pub faces: Vec<[u32; 3]>,
    /// Per-vertex normals, when the file has them.
    pub normals: Option<Vec<[f64; 3]>>,
    /// Per-vertex RGB colors, when the file has them.
    pub colors: Option<Vec<[u8; 3]>>,
}

impl MeshData {
    /// A mesh without normals or colors.
    pub fn new(vertices: Vec<[f64; 3]>, faces: Vec<[u32; 3]>) -> Self {
        Self {
            vertices,
            faces,
            normals: None,
            colors: None,
        }
    }

    /// A point cloud (no faces, no normals, no colors).
    pub fn point_cloud(vertices: Vec<[f64; 3]>) -> Self {
        Self::new(vertices, Vec::new())
    }

    /// `true` when there are no faces.
    pub fn is_point_cloud(&self) -> bool {
        self.faces.is_empty()
    }

    /// Checks that normals, colors and faces are consistent with the vertex count.
    ///
    /// Writers call this before creating any file. Face indices must be below the vertex
    /// count; normals and colors must have one entry per vertex.
    pub fn check_consistency(&self) -> Result<()> {
        let n = self.vertices.len();
        if let Some(normals) = &self.normals {
            if normals.len() != n {
                return Err(FoldMatchError::shape(
                    "normals",
                    format!("{} normals for {} vertices", normals.len(), n),
                ));
            }
        }
        if let Some(colors) = &self.colors {
            if colors.len() != n {
                return Err(FoldMatchError::shape(
                    "colors",
                    format!("{} colors for {} vertices", colors.len(), n),
                ));
            }
        }
        for (i, face) in self.faces.iter().enumerate() {
            for &v in face {
                if v as usize >= n {
                    return Err(FoldMatchError::FaceIndex {
                        name: "faces".into(),
                        face: i,
                        vertex: i64::from(v),
                        count: n,
                    });
                }
            }
        }
        Ok(())
    }
}

/// A named per-vertex `f64` column written to PLY as `property double NAME`
/// (e.g. `wvf_x`, `wvf_y`, `wvf_z`, `wvf_magnitude`).
#[derive(Clone, Debug, PartialEq)]
pub struct VertexProperty {
    /// Property name: non-empty, printable ASCII without spaces, distinct from the standard
    /// names (`x y z nx ny nz red green blue`).
    pub name: String,
    /// One value per vertex.
    pub values: Vec<f64>,
}

impl VertexProperty {
    /// A column named `name` with the given per-vertex values.
    pub fn new(name: impl Into<String>, values: Vec<f64>) -> Self {
        Self {
            name: name.into(),
            values,
        }
    }
}

/// Reads a `.ply` or `.obj` file (the extension decides, in any case).
///
/// # Errors
/// [`FoldMatchError::Format`] for another extension or malformed content,
/// [`FoldMatchError::Io`] when the file cannot be read.
pub fn read_mesh(path: &Path) -> Result<MeshData> {
    match Format::from_path(path)? {
        Format::Ply => read_ply(path),
        Format::Obj => read_obj(path),
    }
}

/// Writes a `.ply` or `.obj` file (the extension decides, in any case), atomically.
///
/// PLY is binary little endian unless `ascii`; `extra` columns are written as
/// `property double NAME`. OBJ is always text and has no place for `extra` columns: they are
/// not written (check `extra.is_empty()` first if dropping them matters).
///
/// # Errors
/// [`FoldMatchError::Format`] for another extension, [`FoldMatchError::Shape`] /
/// [`FoldMatchError::FaceIndex`] / [`FoldMatchError::Parameter`] for inconsistent data (nothing
/// is written then), [`FoldMatchError::Io`] when writing fails.
pub fn write_mesh(
    path: &Path,
    mesh: &MeshData,
    extra: &[VertexProperty],
    ascii: bool,
) -> Result<()> {
    match Format::from_path(path)? {
        Format::Ply => write_ply(path, mesh, extra, ascii),
        Format::Obj => write_obj(path, mesh),
    }
}

/// The file formats known to [`read_mesh`] and [`write_mesh`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Format {
    Ply,
    Obj,
}

impl Format {
    fn from_path(path: &Path) -> Result<Self> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        match ext.as_deref() {
            Some("ply") => Ok(Self::Ply),
            Some("obj") => Ok(Self::Obj),
            Some(other) => Err(format_error(
                &path.display().to_string(),
                0,
                format!("unsupported file extension '.{other}' (expected .ply or .obj)"),
            )),
            None => Err(format_error(
                &path.display().to_string(),
                0,
                "file name has no extension (expected .ply or .obj)",
            )),
        }
    }
}

/// Builds a [`FoldMatchError::Format`].
pub(crate) fn format_error(path: &str, line: usize, reason: impl Into<String>) -> FoldMatchError {
    FoldMatchError::Format {
        path: path.to_string(),
        line,
        reason: reason.into(),
    }
}

/// Builds a [`FoldMatchError::Io`].
pub(crate) fn io_error(path: &Path, source: std::io::Error) -> FoldMatchError {
    FoldMatchError::Io {
        path: path.display().to_string(),
        source,
    }
}

/// Reads a whole file, mapping failures to [`FoldMatchError::Io`], with a bounded allocation:
/// a regular file's size is reserved up front (a failure is [`FoldMatchError::OutOfMemory`]);
/// a FIFO (a pipe given by name, such as `/dev/stdin`) is read up to
/// [`crate::limits::MAX_STREAM_BYTES`]; devices (`/dev/zero`, `/dev/urandom`), sockets and
/// folders are refused, also through symbolic links.
pub fn read_file(path: &Path) -> Result<Vec<u8>> {
    read_bounded(path, crate::limits::MAX_STREAM_BYTES)
}

/// [`read_file`] with `limit` as the most bytes read from a file (regular or not).
pub fn read_bounded(path: &Path, limit: u64) -> Result<Vec<u8>> {
    use std::io::Read;
    let refuse = |what: &str| {
        io_error(
            path,
            std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                format!("{what}: only regular files (or pipes) are read"),
            ),
        )
    };
    // Look before opening: opening a device can have effects of its own.
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let kind = fs::metadata(path)
            .map_err(|e| io_error(path, e))?
            .file_type();
        if kind.is_char_device() || kind.is_block_device() {
            return Err(refuse("a device"));
        }
    }
    let mut file = File::open(path).map_err(|e| io_error(path, e))?;
    let meta = file.metadata().map_err(|e| io_error(path, e))?;
    let kind = meta.file_type();
    let too_large = |size: u64| {
        io_error(
            path,
            std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!("larger than the limit of {limit} bytes ({size} bytes or more)"),
            ),
        )
    };
    // Reads the rest of the file into `data`, refusing more than `limit` bytes.
    let mut read_capped = |mut data: Vec<u8>| -> Result<Vec<u8>> {
        (&mut file)
            .take(limit + 1)
            .read_to_end(&mut data)
            .map_err(|e| io_error(path, e))?;
        if data.len() as u64 > limit {
            return Err(too_large(data.len() as u64));
        }
        Ok(data)
    };
    if kind.is_file() {
        let size = meta.len();
        if size > limit {
            return Err(too_large(size));
        }
        let data = crate::limits::try_vec::<u8>(size as usize + 1, &path.display().to_string())?;
        // The file may grow while it is read: never past the limit.
        return read_capped(data);
    }
    if kind.is_dir() {
        return Err(refuse("a folder"));
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if kind.is_fifo() {
            return read_capped(Vec::new());
        }
        if kind.is_char_device() || kind.is_block_device() {
            return Err(refuse("a device"));
        }
        if kind.is_socket() {
            return Err(refuse("a socket"));
        }
    }
    Err(refuse("not a regular file"))
}

/// Distinguishes temporary files of concurrent writes from the same process.
static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Writes `path` atomically: `emit` writes into a temporary file in the same directory, which
/// is flushed, `fsync`ed and renamed over `path`. On failure the temporary file is removed and
/// `path` is untouched.
pub(crate) fn write_atomically(
    path: &Path,
    emit: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> Result<()> {
    let file_name = path.file_name().ok_or_else(|| {
        io_error(
            path,
            std::io::Error::new(std::io::ErrorKind::InvalidInput, "path has no file name"),
        )
    })?;
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let tmp = dir.join(format!(
        ".{}.tmp.{}.{}",
        file_name.to_string_lossy(),
        std::process::id(),
        TEMP_COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let mut created = false;
    let result = (|| -> std::io::Result<()> {
        let file = OpenOptions::new().write(true).create_new(true).open(&tmp)?;
        created = true;
        let mut writer = BufWriter::with_capacity(1 << 16, file);
        emit(&mut writer)?;
        let file = writer.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        drop(file);
        fs::rename(&tmp, path)
    })();
    match result {
        Ok(()) => {
            // Make the rename itself durable (best effort: not every platform or file system
            // can open and sync a directory).
            #[cfg(unix)]
            if let Ok(d) = File::open(dir) {
                let _ = d.sync_all();
            }
            Ok(())
        }
        Err(e) => {
            if created {
                let _ = fs::remove_file(&tmp);
            }
            Err(io_error(path, e))
        }
    }
}

/// Removes, in `dir`, the temporary files that [`write_atomically`] left when the process
/// writing them was killed mid-write (`.NAME.tmp.PID.N`) and whose target NAME satisfies
/// `target`. Only where no write to such a target is under way; best effort (a file that cannot
/// be listed or removed is left). One listing of `dir`.
#[cfg_attr(not(feature = "cli"), allow(dead_code))] // the batch commands
pub(crate) fn remove_torn_writes(dir: &Path, target: impl Fn(&str) -> bool) {
    let Ok(entries) = fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let name = name.to_string_lossy();
        let torn = name
            .strip_prefix('.')
            .and_then(|rest| rest.rfind(".tmp.").map(|at| &rest[..at]))
            .is_some_and(&target);
        if torn {
            let _ = fs::remove_file(entry.path());
        }
    }
}

/// Runs `emit` on a buffered wrapper of a `Write` sink and flushes it, mapping I/O errors to
/// [`FoldMatchError::Io`] with the pseudo-path `<stream>`.
pub(crate) fn write_to_stream<W: Write>(
    writer: &mut W,
    emit: impl FnOnce(&mut BufWriter<&mut W>) -> std::io::Result<()>,
) -> Result<()> {
    let stream = Path::new("<stream>");
    let mut buffered = BufWriter::with_capacity(1 << 16, writer);
    emit(&mut buffered).map_err(|e| io_error(stream, e))?;
    buffered.flush().map_err(|e| io_error(stream, e))
}

#[cfg(test)]
pub(crate) mod test_util {
    //! Scratch directories for the I/O tests (removed on drop).
    use std::path::{Path, PathBuf};

    /// A fresh directory under the system temp dir, removed when dropped.
    pub struct TempDir(PathBuf);

    impl TempDir {
        pub fn new(tag: &str) -> Self {
            use std::sync::atomic::{AtomicU64, Ordering};
            static N: AtomicU64 = AtomicU64::new(0);
            let dir = std::env::temp_dir().join(format!(
                "foldmatch-io-{tag}-{}-{}",
                std::process::id(),
                N.fetch_add(1, Ordering::Relaxed)
            ));
            std::fs::create_dir_all(&dir).unwrap();
            Self(dir)
        }
        pub fn path(&self) -> &Path {
            &self.0
        }
        pub fn join(&self, name: &str) -> PathBuf {
            self.0.join(name)
        }
        /// Names of the files in the directory, sorted.
        pub fn entries(&self) -> Vec<String> {
            let mut v: Vec<String> = std::fs::read_dir(&self.0)
                .unwrap()
                .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect();
            v.sort();
            v
        }
    }

    impl Drop for TempDir {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    /// A small mesh with a quad-free, non-trivial topology: a unit-ish tetrahedron plus an
    /// isolated vertex, with irrational-looking coordinates to exercise exact round trips.
    pub fn sample_mesh() -> super::MeshData {
        super::MeshData::new(
            vec![
                [0.0, 0.0, 0.0],
                [1.0 / 3.0, -2.5e-7, 1e10],
                [-0.1, 0.7, std::f64::consts::PI],
                [0.5, 0.5, -0.25],
                [123.456, -7.0e-300, 42.0],
            ],
            vec![[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]],
        )
    }
}

#[cfg(test)]
mod tests {
    use super::test_util::{sample_mesh, TempDir};
    use super::*;
    use std::process::Command;

    fn reason(e: &FoldMatchError) -> String {
        e.to_string()
    }

    #[test]
    fn read_mesh_dispatches_on_extension_case_insensitively() {
        let dir = TempDir::new("dispatch");
        let mut mesh = sample_mesh();
        mesh.normals = Some(vec![[0.0, 0.0, 1.0]; 5]);
        for name in ["a.ply", "b.PLY", "c.obj", "d.Obj"] {
            let p = dir.join(name);
            write_mesh(&p, &mesh, &[], false).unwrap();
            assert_eq!(read_mesh(&p).unwrap(), mesh, "{name}");
        }
        let err = read_mesh(&dir.join("x.stl")).unwrap_err();
        assert!(
            reason(&err).contains("unsupported file extension '.stl'"),
            "{err}"
        );
        let err = write_mesh(&dir.join("noext"), &mesh, &[], false).unwrap_err();
        assert!(reason(&err).contains("no extension"), "{err}");
    }

    #[test]
    fn missing_file_is_an_io_error_naming_the_path() {
        let dir = TempDir::new("missing");
        let p = dir.join("nope.ply");
        let err = read_mesh(&p).unwrap_err();
        assert!(matches!(err, FoldMatchError::Io { .. }), "{err:?}");
        assert!(reason(&err).contains("nope.ply"), "{err}");
    }

    /// Issue 31, item 4: devices (also behind a symbolic link) and folders are refused before
    /// anything is read; a pipe is read up to the limit and no further.
    #[cfg(unix)]
    #[test]
    fn non_regular_files_are_refused_or_bounded() {
        let dir = TempDir::new("nonregular");
        let link = dir.join("zero.ply");
        std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
        for path in [Path::new("/dev/zero"), Path::new("/dev/urandom"), &link] {
            let err = read_file(path).unwrap_err();
            assert!(matches!(err, FoldMatchError::Io { .. }), "{err:?}");
            assert!(reason(&err).contains("a device"), "{err}");
        }
        assert!(reason(&read_mesh(&link).unwrap_err()).contains("a device"));
        let folder = dir.join("folder.obj");
        fs::create_dir(&folder).unwrap();
        assert!(reason(&read_mesh(&folder).unwrap_err()).contains("a folder"));
        // A FIFO fed without end: reading stops past the limit.
        let fifo = dir.join("pipe.ply");
        let made = Command::new("mkfifo").arg(&fifo).status();
        if !made.is_ok_and(|s| s.success()) {
            eprintln!("skipping the FIFO case: no mkfifo");
            return;
        }
        let writer_path = fifo.clone();
        let writer = std::thread::spawn(move || {
            let mut f = OpenOptions::new().write(true).open(writer_path).unwrap();
            let chunk = [b'x'; 4096];
            // Until the reader closes its end (broken pipe).
            while f.write_all(&chunk).is_ok() {}
        });
        let err = read_bounded(&fifo, 100_000).unwrap_err();
        assert!(
            reason(&err).contains("larger than the limit of 100000 bytes"),
            "{err}"
        );
        writer.join().unwrap();
        // A regular file over the limit is refused from its size, before reading.
        let big = dir.join("big.ply");
        fs::write(&big, [b'x'; 2000]).unwrap();
        assert!(reason(&read_bounded(&big, 1000).unwrap_err()).contains("2000 bytes"));
        assert_eq!(read_bounded(&big, 2000).unwrap().len(), 2000);
    }

    #[test]
    fn atomic_write_replaces_and_leaves_no_temp_files() {
        let dir = TempDir::new("atomic");
        let p = dir.join("out.ply");
        fs::write(&p, b"old content").unwrap();
        let mesh = sample_mesh();
        write_mesh(&p, &mesh, &[], false).unwrap();
        assert_eq!(read_mesh(&p).unwrap(), mesh);
        assert_eq!(dir.entries(), vec!["out.ply".to_string()]);
        // A writer killed mid-write leaves its temporary file; it is removed for its target only.
        fs::write(dir.join(".out.ply.tmp.99999.0"), b"partial").unwrap();
        fs::write(dir.join(".other.ply.tmp.99999.0"), b"partial").unwrap();
        remove_torn_writes(p.parent().unwrap(), |target| target == "out.ply");
        assert_eq!(
            dir.entries(),
            vec![".other.ply.tmp.99999.0".to_string(), "out.ply".to_string()]
        );
    }

    #[test]
    fn failed_write_keeps_the_old_file_and_removes_the_temp_file() {
        let dir = TempDir::new("atomic-fail");
        let p = dir.join("out.ply");
        fs::write(&p, b"old content").unwrap();
        let err = write_atomically(&p, |w| {
            w.write_all(&[b'x'; 100_000])?;
            Err(std::io::Error::other("disk on fire"))
        })
        .unwrap_err();
        assert!(reason(&err).contains("disk on fire"), "{err}");
        assert_eq!(fs::read(&p).unwrap(), b"old content");
        assert_eq!(dir.entries(), vec!["out.ply".to_string()]);

        // Invalid data is rejected before anything is created.
        let mut bad = sample_mesh();
        bad.faces.push([0, 1, 99]);
        let err = write_mesh(&p, &bad, &[], true).unwrap_err();
        assert!(
            matches!(
                err,
                FoldMatchError::FaceIndex {
                    face: 4,
                    vertex: 99,
                    ..
                }
            ),
            "{err:?}"
        );
        assert_eq!(fs::read(&p).unwrap(), b"old content");
        assert_eq!(dir.entries(), vec!["out.ply".to_string()]);
    }

    #[test]
    fn write_into_missing_directory_is_an_io_error() {
        let dir = TempDir::new("nodir");
        let p = dir.join("sub/out.obj");
        let err = write_mesh(&p, &sample_mesh(), &[], false).unwrap_err();
        assert!(matches!(err, FoldMatchError::Io { .. }), "{err:?}");
        assert!(reason(&err).contains("out.obj"), "{err}");
    }

    #[test]
    fn consistency_checks() {
        let mut m = sample_mesh();
        m.normals = Some(vec![[0.0; 3]; 4]);
        assert!(matches!(
            m.check_consistency(),
            Err(FoldMatchError::Shape { .. })
        ));
        m.normals = None;
        m.colors = Some(vec![[0; 3]; 6]);
        assert!(matches!(
            m.check_consistency(),
            Err(FoldMatchError::Shape { .. })
        ));
        m.colors = None;
        assert!(m.check_consistency().is_ok());
        assert!(MeshData::point_cloud(vec![[1.0; 3]]).is_point_cloud());
    }

    /// Every OBJ of the project's real garment data (`../shared/data`, skipped when absent)
    /// reads with exactly one vertex per `v` line and one triangle per polygon corner beyond
    /// the second, counted here by a naive scan of the text.
    #[test]
    fn reads_the_shared_garment_data() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
        if !root.is_dir() {
            eprintln!("skipping: {} not found", root.display());
            return;
        }
        let mut stack = vec![root];
        let mut n_files = 0;
        while let Some(dir) = stack.pop() {
            for entry in fs::read_dir(&dir).unwrap() {
                let path = entry.unwrap().path();
                if path.is_dir() {
                    stack.push(path);
                    continue;
                }
                if path.extension().and_then(|e| e.to_str()) != Some("obj") {
                    continue;
                }
                let text = fs::read_to_string(&path).unwrap();
                let mut n_v = 0;
                let mut n_tri = 0;
                for line in text.lines() {
                    let mut tokens = line.split_whitespace();
                    match tokens.next() {
                        Some("v") => n_v += 1,
                        Some("f") => n_tri += tokens.count() - 2,
                        _ => {}
                    }
                }
                let mesh = read_mesh(&path).unwrap_or_else(|e| panic!("{e}"));
                assert_eq!(mesh.vertices.len(), n_v, "{}", path.display());
                assert_eq!(mesh.faces.len(), n_tri, "{}", path.display());
                assert!(mesh.check_consistency().is_ok());
                n_files += 1;
            }
        }
        assert!(n_files > 0);
    }

    // ---------------------------------------------------------------------------------------
    // Cross-checks with files written and read by Python's trimesh (skipped without it).
    // ---------------------------------------------------------------------------------------

    /// The Python that has trimesh: `$FOLDMATCH_PYTHON` (set by `make`), else `python3`.
    fn python() -> String {
        std::env::var("FOLDMATCH_PYTHON").unwrap_or_else(|_| "python3".into())
    }

    /// Runs `python -c script args...`; `None` (with the reason printed) when Python or
    /// trimesh is unavailable — except under CI (`CI` set), where that is a failure.
    fn python_trimesh(script: &str, args: &[&Path]) -> Option<String> {
        let skip = |reason: String| -> Option<String> {
            assert!(
                std::env::var_os("CI").is_none(),
                "trimesh cross-check cannot run in CI: {reason}"
            );
            eprintln!("skipping trimesh cross-check: {reason}");
            None
        };
        let probe = Command::new(python())
            .args(["-c", "import trimesh, numpy"])
            .output();
        match probe {
            Ok(o) if o.status.success() => {}
            Ok(o) => {
                let err = String::from_utf8_lossy(&o.stderr);
                return skip(format!(
                    "`import trimesh` failed: {}",
                    err.lines().last().unwrap_or("")
                ));
            }
            Err(e) => return skip(format!("cannot run {}: {e}", python())),
        }
        let out = Command::new(python())
            .arg("-c")
            .arg(script)
            .args(args)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "python script failed:\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        Some(String::from_utf8(out.stdout).unwrap())
    }

    /// Parses the `key: v v v` lines printed by the Python scripts below.
    fn parse_rows(text: &str, key: &str) -> Vec<Vec<f64>> {
        text.lines()
            .filter_map(|l| l.strip_prefix(key))
            .map(|rest| {
                rest.split_whitespace()
                    .map(|t| t.parse::<f64>().unwrap())
                    .collect()
            })
            .collect()
    }

    const TRIMESH_WRITER: &str = r#"
import sys, numpy as np, trimesh
out = sys.argv[1]
rng = np.random.default_rng(7)
m = trimesh.creation.icosphere(subdivisions=1)
m.vertices = m.vertices * [1.0, 2.0, 0.5] + rng.normal(size=(len(m.vertices), 3)) * 0.01
m.vertices = m.vertices.astype(np.float32).astype(np.float64)
colors = rng.integers(0, 256, size=(len(m.vertices), 4)).astype(np.uint8)
m.visual.vertex_colors = colors
m.vertex_attributes['quality'] = rng.normal(size=len(m.vertices))
m.face_attributes['label'] = np.arange(len(m.faces), dtype=np.int32)
normals = m.vertex_normals
with open(out + '/mesh_bin.ply', 'wb') as f:
    f.write(trimesh.exchange.ply.export_ply(m, encoding='binary', vertex_normal=True))
with open(out + '/mesh_ascii.ply', 'wb') as f:
    f.write(trimesh.exchange.ply.export_ply(m, encoding='ascii', vertex_normal=True))
with open(out + '/mesh.obj', 'w') as f:
    f.write(trimesh.exchange.obj.export_obj(m, include_normals=True, include_color=True))
pc = trimesh.PointCloud(rng.normal(size=(50, 3)).astype(np.float32).astype(np.float64))
pc.export(out + '/cloud.ply', encoding='binary')
for v in m.vertices: print('v:', *map(repr, map(float, v)))
for f in m.faces: print('f:', *map(int, f))
for n in normals: print('n:', *map(repr, map(float, n)))
for c in colors: print('c:', *map(int, c))
for v in pc.vertices: print('p:', *map(repr, map(float, v)))
"#;

    #[test]
    fn reads_files_written_by_trimesh() {
        let dir = TempDir::new("trimesh-read");
        let Some(text) = python_trimesh(TRIMESH_WRITER, &[dir.path()]) else {
            return;
        };
        let verts = parse_rows(&text, "v:");
        let faces = parse_rows(&text, "f:");
        let normals = parse_rows(&text, "n:");
        let colors = parse_rows(&text, "c:");
        let cloud = parse_rows(&text, "p:");
        assert_eq!(verts.len(), 42);
        assert_eq!(faces.len(), 80);

        let check = |m: &MeshData, tol: f64, what: &str| {
            assert_eq!(m.vertices.len(), verts.len(), "{what}");
            for (a, b) in m.vertices.iter().zip(&verts) {
                for k in 0..3 {
                    assert!((a[k] - b[k]).abs() <= tol, "{what}: {a:?} vs {b:?}");
                }
            }
            let f: Vec<[u32; 3]> = faces
                .iter()
                .map(|r| [r[0] as u32, r[1] as u32, r[2] as u32])
                .collect();
            assert_eq!(m.faces, f, "{what}");
            let n = m
                .normals
                .as_ref()
                .unwrap_or_else(|| panic!("{what}: normals missing"));
            for (a, b) in n.iter().zip(&normals) {
                for k in 0..3 {
                    // trimesh stores normals as float32 in PLY and with 8 digits in OBJ.
                    assert!((a[k] - b[k]).abs() <= 1e-6, "{what}: {a:?} vs {b:?}");
                }
            }
            let c = m
                .colors
                .as_ref()
                .unwrap_or_else(|| panic!("{what}: colors missing"));
            for (a, b) in c.iter().zip(&colors) {
                assert_eq!(
                    [a[0] as f64, a[1] as f64, a[2] as f64],
                    [b[0], b[1], b[2]],
                    "{what}"
                );
            }
        };
        // PLY stores float32 (the script rounds to float32 first, so these are exact).
        check(
            &read_mesh(&dir.join("mesh_bin.ply")).unwrap(),
            0.0,
            "binary PLY",
        );
        check(
            &read_mesh(&dir.join("mesh_ascii.ply")).unwrap(),
            5e-8,
            "ASCII PLY",
        );
        check(&read_mesh(&dir.join("mesh.obj")).unwrap(), 5e-8, "OBJ");

        let pc = read_mesh(&dir.join("cloud.ply")).unwrap();
        assert!(pc.is_point_cloud());
        assert_eq!(pc.vertices.len(), cloud.len());
        for (a, b) in pc.vertices.iter().zip(&cloud) {
            assert_eq!(a.to_vec(), *b);
        }
    }

    const TRIMESH_READER: &str = r#"
import sys, numpy as np, trimesh
for path in sys.argv[1:]:
    m = trimesh.load(path, process=False)
    kind = 'cloud' if isinstance(m, trimesh.PointCloud) else 'mesh'
    print('file:', path, kind)
    for v in m.vertices: print('v:', *map(repr, map(float, v)))
    if kind == 'mesh':
        for f in m.faces: print('f:', *map(int, f))
        if m.visual.kind == 'vertex':
            for c in m.visual.vertex_colors: print('c:', *map(int, c[:3]))
    # trimesh keeps the raw PLY columns here: a structured array (binary) or a dict (ASCII).
    md = getattr(m, 'metadata', {}) or {}
    raw = md.get('_ply_raw', {}).get('vertex', {}).get('data', None)
    if raw is not None:
        names = raw.dtype.names if hasattr(raw, 'dtype') else raw.keys()
        print('columns:', *names)
        for x in np.asarray(raw['wvf_magnitude']).ravel(): print('w:', repr(float(x)))
"#;

    #[test]
    fn files_written_here_load_in_trimesh() {
        let dir = TempDir::new("trimesh-write");
        let mut mesh = sample_mesh();
        mesh.colors = Some(vec![
            [1, 2, 3],
            [250, 0, 128],
            [7, 7, 7],
            [0, 255, 0],
            [9, 8, 7],
        ]);
        let magnitude: Vec<f64> = (0..5).map(|i| 0.1 * i as f64 + 1.0 / 7.0).collect();
        let extra = [
            VertexProperty::new("wvf_x", vec![1.0; 5]),
            VertexProperty::new("wvf_magnitude", magnitude.clone()),
        ];
        let paths = [
            dir.join("bin.ply"),
            dir.join("ascii.ply"),
            dir.join("mesh.obj"),
        ];
        write_mesh(&paths[0], &mesh, &extra, false).unwrap();
        write_mesh(&paths[1], &mesh, &extra, true).unwrap();
        // trimesh's OBJ loader drops vertices no face uses, so give it a mesh without one.
        let mut obj_mesh = mesh.clone();
        obj_mesh.vertices.truncate(4);
        obj_mesh.colors.as_mut().unwrap().truncate(4);
        write_mesh(&paths[2], &obj_mesh, &[], false).unwrap();
        let refs: Vec<&Path> = paths.iter().map(|p| p.as_path()).collect();
        let Some(text) = python_trimesh(TRIMESH_READER, &refs) else {
            return;
        };
        let sections: Vec<&str> = text.split("file: ").filter(|s| !s.is_empty()).collect();
        assert_eq!(sections.len(), 3, "{text}");
        for (i, section) in sections.iter().enumerate() {
            let mesh = if i < 2 { &mesh } else { &obj_mesh };
            let verts = parse_rows(section, "v:");
            let got: Vec<[f64; 3]> = verts.iter().map(|r| [r[0], r[1], r[2]]).collect();
            assert_eq!(got, mesh.vertices, "file {i}");
            let faces: Vec<[u32; 3]> = parse_rows(section, "f:")
                .iter()
                .map(|r| [r[0] as u32, r[1] as u32, r[2] as u32])
                .collect();
            assert_eq!(faces, mesh.faces, "file {i}");
            let colors: Vec<[u8; 3]> = parse_rows(section, "c:")
                .iter()
                .map(|r| [r[0] as u8, r[1] as u8, r[2] as u8])
                .collect();
            assert_eq!(Some(colors), mesh.colors, "file {i}");
            if i < 2 {
                let w: Vec<f64> = parse_rows(section, "w:").iter().map(|r| r[0]).collect();
                assert_eq!(w, magnitude, "file {i}");
                assert!(section.contains("columns: x y z red green blue wvf_x wvf_magnitude"));
            }
        }
    }
}
