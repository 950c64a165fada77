use super::*;
use crate::error::FoldMatchError;
use crate::io::test_util::{sample_mesh, TempDir};
use crate::io::VertexProperty;

const ENCODINGS: [PlyEncoding; 3] = [
    PlyEncoding::Ascii,
    PlyEncoding::BinaryLittleEndian,
    PlyEncoding::BinaryBigEndian,
];

fn to_bytes(mesh: &MeshData, extra: &[VertexProperty], enc: PlyEncoding) -> Vec<u8> {
    let mut buf = Vec::new();
    write_ply_to(&mut buf, mesh, extra, enc).unwrap();
    buf
}

fn parse(data: &[u8]) -> Result<MeshData> {
    parse_ply(data, "test.ply")
}

fn err_text(data: &[u8]) -> String {
    match parse(data) {
        Ok(m) => panic!("expected an error, got {m:?}"),
        Err(e) => {
            assert!(matches!(e, FoldMatchError::Format { .. }), "{e:?}");
            e.to_string()
        }
    }
}

fn full_mesh() -> MeshData {
    let mut m = sample_mesh();
    m.normals = Some(vec![
        [0.0, 0.0, 1.0],
        [0.6, 0.8, 0.0],
        [-1.0, 0.0, 0.0],
        [0.1, 0.2, 0.3],
        [f64::NAN, 0.0, 0.0],
    ]);
    m.colors = Some(vec![
        [0, 0, 0],
        [255, 255, 255],
        [1, 2, 3],
        [200, 100, 50],
        [9, 9, 9],
    ]);
    m
}

/// Equality that treats NaN as equal to NaN.
fn same(a: &MeshData, b: &MeshData) -> bool {
    let bits = |v: &[[f64; 3]]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
    bits(&a.vertices) == bits(&b.vertices)
        && a.faces == b.faces
        && a.normals.as_deref().map(bits) == b.normals.as_deref().map(bits)
        && a.colors == b.colors
}

#[test]
fn round_trip_all_encodings() {
    for enc in ENCODINGS {
        for mesh in [sample_mesh(), full_mesh()] {
            let bytes = to_bytes(&mesh, &[], enc);
            let back = parse(&bytes).unwrap();
            assert!(same(&back, &mesh), "{enc:?}: {back:?}");
        }
    }
}

#[test]
fn round_trip_point_cloud_with_normals_and_colors() {
    for enc in ENCODINGS {
        let mut pc = MeshData::point_cloud(vec![[1.0, 2.0, 3.0], [-4.5, 1e-9, 6.25]]);
        pc.normals = Some(vec![[0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]);
        pc.colors = Some(vec![[10, 20, 30], [40, 50, 60]]);
        let bytes = to_bytes(&pc, &[], enc);
        assert!(!String::from_utf8_lossy(&bytes).contains("element face"));
        assert_eq!(parse(&bytes).unwrap(), pc, "{enc:?}");
    }
}

#[test]
fn round_trip_through_files() {
    let dir = TempDir::new("ply-files");
    let mesh = full_mesh();
    for (i, enc) in ENCODINGS.into_iter().enumerate() {
        let p = dir.join(&format!("m{i}.ply"));
        write_ply_with_encoding(&p, &mesh, &[], enc).unwrap();
        assert!(same(&read_ply(&p).unwrap(), &mesh), "{enc:?}");
    }
    let p = dir.join("ascii.ply");
    write_ply(&p, &mesh, &[], true).unwrap();
    assert!(std::fs::read(&p)
        .unwrap()
        .starts_with(b"ply\nformat ascii 1.0\n"));
    write_ply(&p, &mesh, &[], false).unwrap();
    assert!(std::fs::read(&p)
        .unwrap()
        .starts_with(b"ply\nformat binary_little_endian 1.0\n"));
}

#[test]
fn extra_properties_are_written_and_skipped_on_read() {
    let mesh = full_mesh();
    let extra = [
        VertexProperty::new("wvf_x", vec![0.5; 5]),
        VertexProperty::new("wvf_magnitude", vec![1.0, 2.0, 3.0, 4.0, 5.0]),
    ];
    for enc in ENCODINGS {
        let bytes = to_bytes(&mesh, &extra, enc);
        let text = String::from_utf8_lossy(&bytes);
        assert!(text.contains("property double wvf_x\nproperty double wvf_magnitude\n"));
        assert!(same(&parse(&bytes).unwrap(), &mesh), "{enc:?}");
    }
    let ascii = String::from_utf8(to_bytes(&sample_mesh(), &extra, PlyEncoding::Ascii)).unwrap();
    let first = ascii
        .lines()
        .find(|l| l.starts_with("0.0 0.0 0.0"))
        .unwrap();
    assert_eq!(first, "0.0 0.0 0.0 0.5 1.0");
}

#[test]
fn bad_extra_properties_are_rejected() {
    let mesh = sample_mesh();
    let cases = [
        (
            VertexProperty::new("wvf", vec![1.0; 4]),
            "4 values for 5 vertices",
        ),
        (
            VertexProperty::new("has space", vec![1.0; 5]),
            "printable ASCII",
        ),
        (VertexProperty::new("", vec![1.0; 5]), "printable ASCII"),
        (VertexProperty::new("red", vec![1.0; 5]), "clashes"),
    ];
    for (p, want) in cases {
        let mut buf = Vec::new();
        let e = write_ply_to(&mut buf, &mesh, &[p], PlyEncoding::Ascii).unwrap_err();
        assert!(e.to_string().contains(want), "{e}");
        assert!(buf.is_empty());
    }
    let dup = [
        VertexProperty::new("a", vec![0.0; 5]),
        VertexProperty::new("a", vec![0.0; 5]),
    ];
    assert!(write_ply_to(&mut Vec::new(), &mesh, &dup, PlyEncoding::Ascii).is_err());
}

#[test]
fn a_requested_vertex_property_is_read_in_every_encoding() {
    let mesh = full_mesh();
    let confidence = vec![0.25, 1.0, 0.0, 0.5, 1e-300];
    let extra = [
        VertexProperty::new("wvf_x", vec![7.0; 5]),
        VertexProperty::new("confidence", confidence.clone()),
    ];
    for enc in ENCODINGS {
        let bytes = to_bytes(&mesh, &extra, enc);
        let (back, values) = parse_ply_property(&bytes, "scan.ply", "confidence").unwrap();
        assert!(same(&back, &mesh), "{enc:?}");
        assert_eq!(values, confidence, "{enc:?}");
        // A property the mesh already holds can be asked for too.
        let (_, red) = parse_ply_property(&bytes, "scan.ply", "red").unwrap();
        assert_eq!(red, [0.0, 255.0, 1.0, 200.0, 9.0], "{enc:?}");
        let (_, x) = parse_ply_property(&bytes, "scan.ply", "x").unwrap();
        let xs: Vec<f64> = mesh.vertices.iter().map(|v| v[0]).collect();
        assert_eq!(x, xs, "{enc:?}");
    }
}

/// What segmenters write: `uchar label` and `float confidence` on a point cloud, ASCII and
/// binary, between the coordinates.
#[test]
fn uchar_labels_and_float_confidence_of_a_point_cloud() {
    let head = |format: &str| {
        format!(
            "ply\nformat {format} 1.0\nelement vertex 3\nproperty float x\n\
             property float y\nproperty uchar label\nproperty float z\n\
             property float confidence\nend_header\n"
        )
    };
    let ascii = head("ascii") + "0 0 1 0 0.5\n1 0 0 0 0.75\n0 1 255 0.5 1\n";
    let mut binary = head("binary_little_endian").into_bytes();
    for (x, y, label, z, c) in [
        (0f32, 0f32, 1u8, 0f32, 0.5f32),
        (1.0, 0.0, 0, 0.0, 0.75),
        (0.0, 1.0, 255, 0.5, 1.0),
    ] {
        binary.extend(x.to_le_bytes());
        binary.extend(y.to_le_bytes());
        binary.push(label);
        binary.extend(z.to_le_bytes());
        binary.extend(c.to_le_bytes());
    }
    for data in [ascii.as_bytes(), binary.as_slice()] {
        let (mesh, label) = parse_ply_property(data, "scan.ply", "label").unwrap();
        assert_eq!(label, [1.0, 0.0, 255.0]);
        assert_eq!(mesh.vertices[2], [0.0, 1.0, 0.5]);
        assert!(mesh.is_point_cloud());
        let (_, c) = parse_ply_property(data, "scan.ply", "confidence").unwrap();
        assert_eq!(c, [0.5, 0.75, 1.0]);
        // The plain reader skips both.
        assert_eq!(parse(data).unwrap(), mesh);
    }
}

#[test]
fn a_missing_or_list_property_is_an_error_naming_file_and_property() {
    let mut h = String::from("ply\nformat ascii 1.0\nelement vertex 2\nproperty double x\n");
    h += "property double y\nproperty double z\nproperty list uchar int labels\n";
    h += "element face 0\nproperty list uchar int vertex_indices\n";
    h += "end_header\n0 0 0 2 1 2\n1 0 0 0\n";
    let err = |prop: &str| match parse_ply_property(h.as_bytes(), "scan.ply", prop) {
        Ok(v) => panic!("{prop}: accepted {v:?}"),
        Err(e) => {
            assert!(matches!(e, FoldMatchError::Format { .. }), "{e:?}");
            e.to_string()
        }
    };
    assert_eq!(
        err("label"),
        "scan.ply:3: vertex element has no property 'label' (it has: x, y, z, labels)"
    );
    assert_eq!(
        err("labels"),
        "scan.ply:3: vertex property 'labels' is a list, expected one number per vertex"
    );
    // Face properties are not vertex properties.
    assert!(err("vertex_indices").contains("no property 'vertex_indices'"));
    // Without a property the file reads as before.
    assert_eq!(parse(h.as_bytes()).unwrap().vertices.len(), 2);
    // Through a file: the path names it.
    let dir = TempDir::new("ply-property");
    let p = dir.join("labelled.ply");
    std::fs::write(&p, &h).unwrap();
    let e = read_ply_property(&p, "label").unwrap_err().to_string();
    assert!(e.starts_with(&format!("{}:3: ", p.display())), "{e}");
    assert!(read_ply_property(&dir.join("none.ply"), "label").is_err());
}

#[test]
fn a_requested_property_of_every_scalar_type_in_binary_with_lists() {
    // The vertex record of the test below: int8 a, float32 x, list junk, int16 y, uint64 b.
    let mut h = String::from("ply\nformat binary_big_endian 1.0\nelement vertex 2\n");
    h += "property int8 a\nproperty float32 x\nproperty list uint8 int16 junk\n";
    h += "property int16 y\nproperty uint64 b\nproperty float64 z\nend_header\n";
    let mut d = h.into_bytes();
    for i in 0..2u8 {
        d.push(0xfe); // a = -2
        d.extend_from_slice(&f32::from(i).to_be_bytes());
        d.push(i);
        for k in 0..i {
            d.extend_from_slice(&i16::from(k).to_be_bytes());
        }
        d.extend_from_slice(&(-300i16).to_be_bytes());
        d.extend_from_slice(&u64::from(i).to_be_bytes());
        d.extend_from_slice(&1.5f64.to_be_bytes());
    }
    let get = |p: &str| parse_ply_property(&d, "t.ply", p).unwrap().1;
    assert_eq!(get("a"), [-2.0, -2.0]);
    assert_eq!(get("y"), [-300.0, -300.0]);
    assert_eq!(get("b"), [0.0, 1.0]);
    assert_eq!(get("z"), [1.5, 1.5]);
    let e = parse_ply_property(&d, "t.ply", "junk")
        .unwrap_err()
        .to_string();
    assert!(e.contains("'junk' is a list"), "{e}");
    // Truncated: the same errors as without a property.
    let e = parse_ply_property(&d[..d.len() - 1], "t.ply", "a").unwrap_err();
    assert!(e.to_string().contains("truncated"), "{e}");
}

#[test]
fn all_scalar_types_lists_on_vertices_and_unknown_elements() {
    // Little-endian binary with every type, a list on the vertex element, an unknown
    // element with a list before the faces, and a quad plus a triangle.
    let mut h = String::from("ply\r\nformat binary_little_endian 1.0\r\ncomment hi\r\n");
    h += "obj_info made by hand\r\nelement vertex 4\r\n";
    h += "property int8 a\r\nproperty float32 x\r\nproperty list uint8 int16 junk\r\n";
    h += "property int16 y\r\nproperty uint64 b\r\nproperty float64 z\r\n";
    h += "property uint16 red\r\nproperty uint32 green\r\nproperty int32 blue\r\n";
    h += "element material 2\r\nproperty list ushort double coeffs\r\nproperty uchar id\r\n";
    h += "element face 2\r\nproperty uchar flags\r\nproperty list uint uint vertex_index\r\n";
    h += "element edge 3\r\nproperty int v1\r\nproperty int v2\r\n";
    h += "end_header\r\n";
    let mut d = h.into_bytes();
    for i in 0..4u8 {
        d.push(0xff); // a
        d.extend_from_slice(&(f32::from(i) + 0.5).to_le_bytes()); // x
        d.push(i); // junk: i items of int16
        for k in 0..i {
            d.extend_from_slice(&(i16::from(k)).to_le_bytes());
        }
        d.extend_from_slice(&(-(i16::from(i))).to_le_bytes()); // y
        d.extend_from_slice(&u64::MAX.to_le_bytes()); // b
        d.extend_from_slice(&(f64::from(i) * 0.25).to_le_bytes()); // z
        d.extend_from_slice(&300u16.to_le_bytes()); // red (clamped)
        d.extend_from_slice(&u32::from(i).to_le_bytes()); // green
        d.extend_from_slice(&(-5i32).to_le_bytes()); // blue (clamped)
    }
    for k in 0..2u16 {
        d.extend_from_slice(&(k + 1).to_le_bytes());
        for j in 0..=k {
            d.extend_from_slice(&f64::from(j).to_le_bytes());
        }
        d.push(7);
    }
    d.push(0);
    d.extend_from_slice(&4u32.to_le_bytes());
    for v in [0u32, 1, 2, 3] {
        d.extend_from_slice(&v.to_le_bytes());
    }
    d.push(0);
    d.extend_from_slice(&3u32.to_le_bytes());
    for v in [3u32, 2, 1] {
        d.extend_from_slice(&v.to_le_bytes());
    }
    d.extend_from_slice(&[0u8; 24]); // edges
    let m = parse(&d).unwrap();
    // The same file with a 2-gon for the triangle is an error naming the face (issue 31:
    // PLY faces of 0 or 2 indices are errors, as OBJ's `f 1 2`).
    let mut two = d.clone();
    let at = two.len() - 24 - 16;
    two[at..at + 4].copy_from_slice(&2u32.to_le_bytes());
    two.drain(at + 12..at + 16);
    let err = parse(&two).unwrap_err().to_string();
    assert!(
        err.contains("face 1 has 2 vertices, at least 3 are needed"),
        "{err}"
    );
    assert_eq!(
        m.vertices,
        vec![
            [0.5, 0.0, 0.0],
            [1.5, -1.0, 0.25],
            [2.5, -2.0, 0.5],
            [3.5, -3.0, 0.75]
        ]
    );
    assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3], [3, 2, 1]]);
    assert_eq!(
        m.colors.unwrap(),
        vec![[255, 0, 0], [255, 1, 0], [255, 2, 0], [255, 3, 0]]
    );
    assert!(m.normals.is_none());
}

#[test]
fn ascii_variants() {
    let text = "ply\nformat ascii 1.0\nelement vertex 4\nproperty uchar red\n\
        property double x\nproperty float y\nproperty float z\nproperty float nx\n\
        property float ny\nproperty float nz\nproperty list uchar int extra\n\
        property uchar green\nproperty uchar blue\n\
        element face 2\nproperty list uchar int vertex_indices\nproperty float q\n\
        end_header\n\
        1 0 0 0 0 0 1 0 2 3\n\
        \n\
        2.0 1e0 NaN -inf 1 0 0 2 5 6 4 5\n\
        3 0 1 0 0 1 0 1 9 6 7\n\
        4 1 1 0 0.5 0.5 0 3 1 2 3 8 9\n\
        4 0 1 2 3 0.5\n\
        3 3 2 1 -1";
    let m = parse(text.as_bytes()).unwrap();
    assert_eq!(m.vertices[0], [0.0, 0.0, 0.0]);
    assert_eq!(m.vertices[1][0], 1.0);
    assert!(m.vertices[1][1].is_nan(), "NaN is read as-is");
    assert_eq!(m.vertices[1][2], f64::NEG_INFINITY);
    assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3], [3, 2, 1]]);
    assert_eq!(
        m.colors.unwrap(),
        vec![[1, 2, 3], [2, 4, 5], [3, 6, 7], [4, 8, 9]]
    );
    assert_eq!(m.normals.unwrap()[3], [0.5, 0.5, 0.0]);
}

#[test]
fn float_colors_are_scaled() {
    let text = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n\
        property float y\nproperty float z\nproperty float red\nproperty float green\n\
        property float blue\nend_header\n0 0 0 1.0 0.5 0\n";
    assert_eq!(
        parse(text.as_bytes()).unwrap().colors.unwrap(),
        vec![[255, 128, 0]]
    );
}

#[test]
fn empty_file() {
    assert!(err_text(b"").contains("test.ply:0: empty file"));
}

#[test]
fn non_ply_binary_file() {
    let junk: Vec<u8> = (0..200u32).map(|i| (i * 37 % 251) as u8).collect();
    let e = err_text(&junk);
    assert!(
        e.contains("test.ply:1: not a PLY file (missing 'ply' magic)"),
        "{e}"
    );
    assert!(err_text(b"plyfoo\n").contains("missing 'ply' magic"));
    // An OBJ renamed .ply
    assert!(err_text(b"v 0 0 0\n").contains("missing 'ply' magic"));
}

#[test]
fn huge_header_counts_are_rejected_before_allocating() {
    for enc in ["binary_little_endian", "binary_big_endian", "ascii"] {
        let mut d = format!(
            "ply\nformat {enc} 1.0\nelement vertex 1000000000\nproperty float x\n\
             property float y\nproperty float z\nend_header\n"
        )
        .into_bytes();
        d.resize(1024, b'0');
        let e = err_text(&d);
        assert!(
            e.contains("test.ply:3: header announces 1000000000 vertices"),
            "{e}"
        );
        assert!(e.contains("but the file holds at most"), "{e}");
    }
    // Exactly at the limit for faces: the face count is checked after the vertices.
    let mut d = b"ply\nformat binary_little_endian 1.0\nelement vertex 1\n\
        property float x\nproperty float y\nproperty float z\n\
        element face 18446744073709551615\nproperty list uchar int vertex_indices\n\
        end_header\n"
        .to_vec();
    d.extend_from_slice(&[0u8; 12 + 5]);
    let e = err_text(&d);
    assert!(
        e.contains(":7: header announces 18446744073709551615 faces but the file holds at most 5"),
        "{e}"
    );
    // An unknown element with a huge count.
    let d = b"ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float x\n\
        property float y\nproperty float z\nelement junk 99999999999\nproperty double w\n\
        end_header\n";
    assert!(err_text(d).contains("header announces 99999999999 'junk' elements"));
    // A count that does not fit in usize.
    let d = b"ply\nformat ascii 1.0\nelement vertex 99999999999999999999999\nend_header\n";
    assert!(err_text(d).contains(":3: element 'vertex': invalid count"));
}

#[test]
fn truncated_files() {
    let mesh = full_mesh();
    for enc in [
        PlyEncoding::BinaryLittleEndian,
        PlyEncoding::BinaryBigEndian,
    ] {
        let bytes = to_bytes(&mesh, &[], enc);
        let header_len = bytes
            .windows(11)
            .position(|w| w == b"end_header\n")
            .unwrap()
            + 11;
        for cut in [header_len + 1, header_len + 100, bytes.len() - 1] {
            let e = err_text(&bytes[..cut]);
            assert!(
                e.contains("header announces") || e.contains("truncated file"),
                "{enc:?} cut {cut}: {e}"
            );
        }
    }
    // A list that runs past the end (passes the size check, fails while reading).
    let mut d = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\n\
        property uchar x\nproperty uchar y\nproperty uchar z\n\
        element face 1\nproperty list uchar int vertex_indices\nend_header\n"
        .to_vec();
    d.extend_from_slice(&[0u8; 9]);
    d.extend_from_slice(&[3, 0, 0, 0, 0, 1, 0]);
    let e = err_text(&d);
    assert!(
        e.contains("test.ply:0: truncated file: face record 0 of 1"),
        "{e}"
    );

    let bytes = to_bytes(&mesh, &[], PlyEncoding::Ascii);
    let text = String::from_utf8(bytes).unwrap();
    let cut: String = text
        .lines()
        .take(text.lines().count() - 2)
        .collect::<Vec<_>>()
        .join("\n");
    let e = err_text(cut.as_bytes());
    assert!(
        e.contains("truncated file: expected 4 faces, found 2"),
        "{e}"
    );
    // Header without end_header.
    let e = err_text(b"ply\nformat ascii 1.0\nelement vertex 1\n");
    assert!(
        e.contains(":4: header is not terminated by 'end_header'"),
        "{e}"
    );
}

#[test]
fn face_index_out_of_range_names_the_face() {
    let bytes = to_bytes(&sample_mesh(), &[], PlyEncoding::Ascii);
    let text = String::from_utf8(bytes.clone())
        .unwrap()
        .replace("3 1 3 2", "3 1 5 2");
    let e = err_text(text.as_bytes());
    let last = text.lines().count();
    assert!(
        e.contains(&format!(
            "test.ply:{last}: face 3 refers to vertex 5, but there are only 5 vertices"
        )),
        "{e}"
    );
    let text = String::from_utf8(bytes)
        .unwrap()
        .replace("3 0 1 2", "3 0 -1 2");
    assert!(err_text(text.as_bytes()).contains("face 0 refers to vertex -1"));
    // Binary: overwrite the last index of the last face.
    let bytes_le = {
        let mut b = to_bytes(&sample_mesh(), &[], PlyEncoding::BinaryLittleEndian);
        let n = b.len();
        b[n - 4..].copy_from_slice(&7i32.to_le_bytes());
        b
    };
    let e = err_text(&bytes_le);
    assert!(e.contains("test.ply:0: face 3 refers to vertex 7"), "{e}");
}

#[test]
fn malformed_ascii_lines_name_the_line() {
    let good = String::from_utf8(to_bytes(&sample_mesh(), &[], PlyEncoding::Ascii)).unwrap();
    let lines: Vec<&str> = good.lines().collect();
    let header_lines = lines.iter().position(|l| *l == "end_header").unwrap() + 1;
    let third_vertex_line = header_lines + 3;
    let mut bad = lines.clone();
    bad[third_vertex_line - 1] = "0.1 zero 3";
    let e = err_text(bad.join("\n").as_bytes());
    assert!(
        e.contains(&format!(
            "test.ply:{third_vertex_line}: vertex 2: cannot parse 'zero' as double (property 'y')"
        )),
        "{e}"
    );
    bad[third_vertex_line - 1] = "0.1 0.2";
    let e = err_text(bad.join("\n").as_bytes());
    assert!(
        e.contains(&format!(":{third_vertex_line}: vertex 2: too few values")),
        "{e}"
    );
    bad[third_vertex_line - 1] = "0.1 0.2 0.3 0.4";
    let e = err_text(bad.join("\n").as_bytes());
    assert!(
        e.contains(&format!(":{third_vertex_line}: vertex 2: more values")),
        "{e}"
    );
    let mut bad = lines.clone();
    let n = bad.len();
    bad[n - 1] = "3 1 2.5 3";
    let e = err_text(bad.join("\n").as_bytes());
    assert!(
        e.contains(&format!(":{n}: face 3: cannot parse '2.5' as int")),
        "{e}"
    );
    bad[n - 1] = "-3 1 2 3";
    assert!(err_text(bad.join("\n").as_bytes()).contains("negative list count -3"));
    bad[n - 1] = "300 1 2 3";
    assert!(err_text(bad.join("\n").as_bytes()).contains("too few values"));
}

#[test]
fn header_errors() {
    let cases: &[(&str, &str)] = &[
        ("ply\nformat xml 1.0\nend_header\n", ":2: unknown format 'xml'"),
        ("ply\nformat ascii 1.0\nend_header\n", "no 'vertex' element"),
        ("ply\nelement vertex 1\nproperty float x\nend_header\n", "no 'format' line"),
        ("ply\nformat ascii 1.0\nproperty float x\nend_header\n", ":3: 'property' before"),
        ("ply\nformat ascii 1.0\nelement vertex 1\nproperty half x\nend_header\n", ":4: unknown property type 'half'"),
        ("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n0\n", "no 'y' property"),
        ("ply\nformat ascii 1.0\nelement vertex 1\nfoo bar\nend_header\n", ":4: unexpected header line"),
        (
            "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n\
             property float z\nelement face 0\nproperty int flags\nend_header\n",
            ":7: face element has no 'vertex_indices'",
        ),
        (
            "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n\
             property float z\nelement face 0\nproperty list float int vertex_indices\nend_header\n",
            ":8: list 'vertex_indices': count type 'float' is not an integer type",
        ),
        (
            "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n\
             property float z\nelement face 0\nproperty list uchar float vertex_indices\nend_header\n",
            "expected an integer type",
        ),
        (
            "ply\nformat ascii 1.0\nelement vertex 0\nelement vertex 0\nend_header\n",
            ":4: second 'vertex' element",
        ),
    ];
    for (text, want) in cases {
        let e = err_text(text.as_bytes());
        assert!(e.contains(want), "{text:?}: {e}");
    }
}

/// Deterministic mutation fuzzing: flipped bytes, truncations and spliced digits must give
/// `Ok` or `Err`, never a panic or a runaway allocation.
#[test]
fn mutated_files_never_panic() {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut rand = move |n: usize| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state % n as u64) as usize
    };
    let extra = [VertexProperty::new("q", vec![0.5; 5])];
    for enc in ENCODINGS {
        let good = to_bytes(&full_mesh(), &extra, enc);
        for _ in 0..2000 {
            let mut d = good.clone();
            match rand(4) {
                0 => d.truncate(rand(good.len())),
                1 => {
                    for _ in 0..1 + rand(4) {
                        let i = rand(d.len());
                        d[i] = rand(256) as u8;
                    }
                }
                2 => {
                    let i = rand(d.len());
                    d.splice(i..i, b"99999999999".iter().copied());
                }
                _ => {
                    let i = rand(d.len());
                    let alphabet = b"0123456789 \n-.e";
                    d[i] = alphabet[rand(alphabet.len())];
                }
            }
            let _ = parse(&d);
            let _ = crate::io::parse_obj(&d, "fuzz.obj");
        }
    }
}

#[test]
fn empty_mesh_and_no_trailing_newline() {
    let m = parse(
        b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n\
          property float z\nend_header\n",
    )
    .unwrap();
    assert_eq!(m, MeshData::default());
    let m = parse(
        b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
          property float z\nend_header\n1 2 3",
    )
    .unwrap();
    assert_eq!(m.vertices, vec![[1.0, 2.0, 3.0]]);
}
