//! Hostile and damaged files: each gets a clean error naming the problem, never a panic
//! or an allocation of what a header claims (this test process would abort on one: the
//! forged sizes below are 1 TiB and more).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly

use std::io::Write;
use std::path::{Path, PathBuf};

use base64::Engine;
use fluidcast_io::{parse_collection, parse_dataset, read_dataset};

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/fixtures")
        .join(name)
}

/// The error message for `bytes` read as a file named `name`.
fn refused(bytes: &[u8], name: &str) -> String {
    match parse_dataset(bytes, Path::new(name)) {
        Ok(_) => panic!("{name}: accepted"),
        Err(e) => {
            let m = e.to_string();
            assert!(m.starts_with(name), "error does not name the file: {m}");
            m
        }
    }
}

const B64: base64::engine::GeneralPurpose = base64::engine::general_purpose::STANDARD;

/// One point (three Float32) with its payload inline as base64, and the file's attributes.
fn inline_vtu(file_attrs: &str, payload: &[u8]) -> Vec<u8> {
    format!(
        r#"<?xml version="1.0"?><VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64" {file_attrs}><UnstructuredGrid><Piece NumberOfPoints="1" NumberOfCells="0"><Points><DataArray type="Float32" NumberOfComponents="3" format="binary">{}</DataArray></Points></Piece></UnstructuredGrid></VTKFile>"#,
        B64.encode(payload)
    )
    .into_bytes()
}

/// A file whose data set is `body` and whose one appended payload is `payload` (raw or
/// base64), ending as VTK ends it.
fn with_appended(file_attrs: &str, body: &str, payload: &[u8], base64: bool) -> Vec<u8> {
    let mut out = format!(
        r#"<?xml version="1.0"?><VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64" {file_attrs}><UnstructuredGrid>{body}</UnstructuredGrid><AppendedData encoding="{}">_"#,
        if base64 { "base64" } else { "raw" }
    )
    .into_bytes();
    if base64 {
        out.extend(B64.encode(payload).bytes());
    } else {
        out.extend_from_slice(payload);
    }
    out.extend_from_slice(b"\n</AppendedData></VTKFile>\n");
    out
}

/// The same point as appended data (raw or base64).
fn appended_vtu(file_attrs: &str, payload: &[u8], base64: bool) -> Vec<u8> {
    let body = r#"<Piece NumberOfPoints="1" NumberOfCells="0"><Points><DataArray type="Float32" NumberOfComponents="3" format="appended" offset="0"/></Points></Piece>"#;
    with_appended(file_attrs, body, payload, base64)
}

fn words(w: &[u64]) -> Vec<u8> {
    w.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn compress(c: &str, data: &[u8]) -> Vec<u8> {
    match c {
        "vtkZLibDataCompressor" => {
            let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
            e.write_all(data).unwrap();
            e.finish().unwrap()
        }
        "vtkLZ4DataCompressor" => lz4_flex::block::compress(data),
        _ => {
            let mut out = Vec::new();
            lzma_rs::xz_compress(&mut std::io::Cursor::new(data), &mut out).unwrap();
            out
        }
    }
}

/// Every container (inline binary, appended raw, appended base64) around `payload`.
fn containers(compressor: &str, payload: &[u8]) -> Vec<(String, Vec<u8>)> {
    let attrs = format!(r#"compressor="{compressor}""#);
    vec![
        ("inline".into(), inline_vtu(&attrs, payload)),
        ("raw".into(), appended_vtu(&attrs, payload, false)),
        ("base64".into(), appended_vtu(&attrs, payload, true)),
    ]
}

const COMPRESSORS: [&str; 3] = [
    "vtkZLibDataCompressor",
    "vtkLZ4DataCompressor",
    "vtkLZMADataCompressor",
];

#[test]
fn forged_block_sizes_are_refused_before_allocating() {
    let twelve = [0u8; 12];
    for c in COMPRESSORS {
        let blk = compress(c, &twelve);
        let forged: [(&str, Vec<u64>); 4] = [
            ("1 TiB block", vec![1, 1 << 40, 1 << 40, blk.len() as u64]),
            ("3 GiB last block", vec![1, 12, 3 << 30, blk.len() as u64]),
            ("100 blocks of 1 GiB", {
                let mut w = vec![100, 1 << 30, 0];
                w.extend([blk.len() as u64; 100]);
                w
            }),
            ("overflowing 2 x 2^63", vec![2, 1 << 63, 0, 5, 5]),
        ];
        for (what, hdr) in forged {
            let mut payload = words(&hdr);
            payload.extend_from_slice(&blk);
            for (container, file) in containers(c, &payload) {
                let e = refused(&file, "forged.vtu");
                assert!(
                    e.contains("compression header") || e.contains("more than the file holds"),
                    "{c} {what} {container}: {e}"
                );
            }
        }
    }
}

#[test]
fn decompression_bombs_stop_at_the_declared_size() {
    // A header saying 12 bytes over streams that give 64 MiB: refused at byte 13.
    let big = vec![0u8; 64 << 20];
    for c in ["vtkZLibDataCompressor", "vtkLZMADataCompressor"] {
        let blk = compress(c, &big);
        let mut payload = words(&[1, 12, 12, blk.len() as u64]);
        payload.extend_from_slice(&blk);
        for (container, file) in containers(c, &payload) {
            let e = refused(&file, "bomb.vtu");
            assert!(
                e.contains("more bytes than its header states"),
                "{c} {container}: {e}"
            );
        }
    }
    // lz4 cannot expand a block beyond 255:1: a bigger claim is refused unread.
    let blk = compress("vtkLZ4DataCompressor", &[0u8; 12]);
    let mut payload = words(&[1, 12, 12, blk.len() as u64]);
    payload.extend_from_slice(&blk);
    let file = appended_vtu(r#"compressor="vtkLZ4DataCompressor""#, &payload, false);
    assert!(parse_dataset(&file, Path::new("ok.vtu")).is_ok());
}

#[test]
fn uncompressed_lengths_near_2_pow_64() {
    for n in (0..8).map(|k| u64::MAX - k) {
        let mut payload = n.to_le_bytes().to_vec();
        payload.extend_from_slice(&[0; 12]);
        for file in [
            inline_vtu("", &payload),
            appended_vtu("", &payload, true),
            appended_vtu("", &payload, false),
        ] {
            let e = refused(&file, "len.vtu");
            assert!(e.contains("data header says"), "{n}: {e}");
        }
    }
    // An empty appended section: the header is missing, not 7236833184825028412 bytes.
    let e = refused(&appended_vtu("", &[], false), "empty.vtu");
    assert!(e.contains("data header is truncated"), "{e}");
}

#[test]
fn the_reader_is_as_strict_as_vtk() {
    let good = std::fs::read(fixture("lattice_appended-raw_none_h64.vtu")).unwrap();
    let ascii = std::fs::read(fixture("lattice_ascii_none_h64.vtu")).unwrap();
    let edit = |src: &[u8], from: &str, to: &str| {
        String::from_utf8_lossy(src)
            .replacen(from, to, 1)
            .into_bytes()
    };
    let cases: Vec<(&str, Vec<u8>, &str)> =
        vec![
        (
            "byte order",
            edit(&ascii, "LittleEndian", "MiddleEndian"),
            "unknown byte_order 'MiddleEndian'",
        ),
        (
            "encoding",
            edit(&good, r#"encoding="raw""#, r#"encoding="hex""#),
            "unknown <AppendedData> encoding 'hex'",
        ),
        (
            "UInt64 headers labelled UInt32",
            edit(&good, r#"header_type="UInt64""#, r#"header_type="UInt32""#),
            // Named whichever array is decoded first (the points: a header of the wrong
            // size; a point array: a payload that does not end at the next offset).
            "header_type",
        ),
        (
            "unclosed tag",
            edit(&ascii, "<DataArray", r#"<InformationKey name="x" <DataArray"#),
            "'<' inside the <InformationKey> tag",
        ),
        ("trailing garbage", [ascii.clone(), b"garbage".to_vec()].concat(), "after </VTKFile>"),
        (
            "truncated after the point data",
            ascii[..String::from_utf8_lossy(&ascii).rfind("</Piece>").unwrap()].to_vec(),
            "still open",
        ),
        (
            "truncated appended data",
            good[..good.len() - 30].to_vec(),
            "does not end with </AppendedData></VTKFile>",
        ),
        (
            "no data-set element",
            br#"<?xml version="1.0"?><VTKFile type="UnstructuredGrid" version="1.0"></VTKFile>"#
                .to_vec(),
            "no <UnstructuredGrid> or <PolyData> element",
        ),
    ];
    for (what, bytes, expect) in cases {
        let e = refused(&bytes, "strict.vtu");
        assert!(e.contains(expect), "{what}: {e}");
    }
    // A UInt8 value of 300 is out of range.
    let u8_file = String::from_utf8_lossy(&ascii).replacen(
        r#"<PointData>"#,
        r#"<PointData><DataArray type="UInt8" Name="f" format="ascii">300 0 0 0 0 0 0 0</DataArray>"#,
        1,
    );
    let e = refused(u8_file.as_bytes(), "u8.vtu");
    assert!(e.contains("300 is out of range for UInt8"), "{e}");
    // A float beyond Float32 is out of range; a literal inf or nan is a value.
    let f = String::from_utf8_lossy(&ascii).replacen(
        r#"<PointData>"#,
        r#"<PointData><DataArray type="Float32" Name="g" format="ascii">1e39</DataArray>"#,
        1,
    );
    assert!(refused(f.as_bytes(), "f.vtu").contains("'1e39' is out of range for Float32"));
}

#[test]
fn legacy_errors_name_the_line() {
    let cases: [(&[u8], &str); 5] = [
        (
            b"# vtk DataFile Version 4.2\nx\nASCII\nDATASET POLYDATA\nPOINTS 2 float\n0 0 0 1 1\n",
            "line 6: 6 values announced, the file has 10 bytes left (file truncated?)",
        ),
        (
            b"# vtk DataFile Version 4.2\nx\nHEX\nDATASET POLYDATA\n",
            "line 3: expected ASCII or BINARY, found 'HEX'",
        ),
        (
            b"# vtk DataFile Version 4.2\nx\nASCII\nDATASET STRUCTURED_POINTS\n",
            "line 4: DATASET STRUCTURED_POINTS is not particle data",
        ),
        (
            b"# vtk DataFile Version 4.2\nx\nBINARY\nDATASET POLYDATA\nPOINTS 1000000000000 float\n\0\0",
            "line 6: 3000000000000 Float32 values need 12000000000000 bytes",
        ),
        (
            b"# vtk DataFile Version 4.2\nx\nASCII\nDATASET POLYDATA\nPOINTS 1 float\n0 0 0\nPOINT_DATA 1\nSCALARS s unsigned_char\nLOOKUP_TABLE default\n300\n",
            "line 10: 300 is out of range for UInt8",
        ),
    ];
    for (bytes, expect) in cases {
        let e = refused(bytes, "legacy.vtk");
        assert!(e.contains(expect), "{e}");
    }
    let full = std::fs::read(fixture("lattice_legacy42_binary.vtk")).unwrap();
    let e = refused(&full[..full.len() / 2], "cut.vtk");
    // After binary data, newlines in it make line numbers meaningless: the byte is named.
    assert!(e.contains("truncated") && e.contains(": byte "), "{e}");
}

#[test]
fn collections_name_what_is_wrong() {
    let pvd = br#"<?xml version="1.0"?><VTKFile type="Collection"><Collection><DataSet timestep="0" file="nope.vtu"/></Collection></VTKFile>"#;
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("series.pvd");
    std::fs::write(&p, pvd).unwrap();
    let input = fluidcast_io::Input::open(&p).unwrap();
    let (_, file) = input.frames().remove(0);
    let e = input.read(&file).unwrap_err().to_string();
    assert!(
        e.contains("nope.vtu (listed in") && e.contains("series.pvd"),
        "{e}"
    );
    let e = refused(pvd, "inner.pvd");
    assert!(e.contains("a .pvd cannot list another .pvd"), "{e}");
    let e = parse_collection(
        br#"<VTKFile type="Collection"><Collection><DataSet timestep="0" file="a.vtu"/>"#,
        Path::new("cut.pvd"),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("cut.pvd") && e.contains("no </Collection>"),
        "{e}"
    );
}

#[test]
fn collections_tell_the_times_that_list_several_data_sets() {
    let c = parse_collection(
        br#"<VTKFile type="Collection"><Collection>
        <DataSet timestep="0.2" part="1" file="b.vtu"/><DataSet timestep="0.1" file="a.vtu"/>
        <DataSet timestep="0.2" part="0" file="c.vtu"/><DataSet timestep="0.3" file="d.vtu"/>
        <DataSet timestep="0.3" file="e.vtu"/><DataSet timestep="0.3" file="f.vtu"/>
        </Collection></VTKFile>"#,
        Path::new("parts.pvd"),
    )
    .unwrap();
    assert_eq!(c.shared_times(), [(0.2, 2), (0.3, 3)]);
    let one = parse_collection(
        br#"<VTKFile type="Collection"><Collection><DataSet timestep="0" file="a.vtu"/>
        <DataSet timestep="1" file="b.vtu"/></Collection></VTKFile>"#,
        Path::new("one.pvd"),
    )
    .unwrap();
    assert!(one.shared_times().is_empty());
}

#[test]
fn devices_and_pipes_are_refused_without_blocking() {
    let e = read_dataset("/dev/zero").unwrap_err().to_string();
    assert!(e.contains("unsupported file extension"), "{e}");
    let e = fluidcast_io::read_file(Path::new("/dev/zero"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("/dev/zero: is a character device, not a regular file"),
        "{e}"
    );
    // FIFOs with no writer, as the file itself, a parallel file's piece and a .pvd's data
    // set: an open that waited for a writer would hang here.
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("fifo.vtu");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap();
    assert!(made.success(), "mkfifo failed");
    let pvtu = dir.path().join("run.pvtu");
    std::fs::write(
        &pvtu,
        r#"<VTKFile type="PUnstructuredGrid" version="0.1"><PUnstructuredGrid GhostLevel="0">
        <PPoints><PDataArray type="Float32" NumberOfComponents="3"/></PPoints>
        <Piece Source="fifo.vtu"/></PUnstructuredGrid></VTKFile>"#,
    )
    .unwrap();
    let pvd = dir.path().join("run.pvd");
    std::fs::write(
        &pvd,
        r#"<VTKFile type="Collection"><Collection><DataSet timestep="0" file="fifo.vtu"/>
        </Collection></VTKFile>"#,
    )
    .unwrap();
    for e in [
        read_dataset(&fifo).unwrap_err().to_string(),
        fluidcast_io::open_lazy(&fifo, &fluidcast_io::Arrays::All)
            .err()
            .unwrap()
            .to_string(),
        read_dataset(&pvtu).unwrap_err().to_string(),
        fluidcast_io::cells_of(&fifo).unwrap_err().to_string(),
    ] {
        assert!(
            e.contains("fifo.vtu") && e.contains("a FIFO (named pipe)"),
            "{e}"
        );
    }
    let input = fluidcast_io::Input::open(&pvd).unwrap();
    let frame = input.frames().remove(0);
    let e = input
        .read_frame(&frame, &fluidcast_io::Arrays::All)
        .unwrap_err()
        .to_string();
    assert!(e.contains("a FIFO (named pipe)"), "{e}");
}

#[test]
fn hand_written_legacy_files_as_sph_codes_write_them() {
    // Version 3.1, upper-case type names, one polyvertex cell, blank lines, SCALARS without
    // a LOOKUP_TABLE line, a VECTORS section, Windows line ends.
    let text =
        "# vtk DataFile Version 3.1\r\nSimulation frame\r\nASCII\r\nDATASET UNSTRUCTURED_GRID\r\n\
                POINTS 3 FLOAT\r\n0 0 0\r\n1 0 0\r\n0 1 0\r\n\r\nCELLS 1 4\r\n3 0 1 2\r\n\r\n\
                CELL_TYPES 1\r\n2\r\n\r\nPOINT_DATA 3\r\nSCALARS rho DOUBLE 1\r\n1000 1001 1002\r\n\
                VECTORS v FLOAT\r\n1 0 0 0 1 0 0 0 1\r\n";
    let d =
        parse_dataset(text.as_bytes(), Path::new("frame.vtk")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        d.points,
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
    );
    assert_eq!(
        d.point_array("rho").unwrap().values,
        vec![1000.0, 1001.0, 1002.0]
    );
    let v = d.point_array("v").unwrap();
    assert_eq!((v.num_components, v.values[4]), (3, 1.0));
}

/// A field-data array without `NumberOfTuples`: the only size is the payload's own header,
/// so every bound must come from the file itself.
fn undeclared_field_array(file_attrs: &str, payload: &[u8], base64: bool) -> Vec<u8> {
    let body = r#"<FieldData><DataArray type="Float32" Name="f" format="appended" offset="0"/></FieldData><Piece NumberOfPoints="0" NumberOfCells="0"/>"#;
    with_appended(file_attrs, body, payload, base64)
}

#[test]
fn undeclared_sizes_are_bounded_by_the_file() {
    let field = |file: &[u8]| parse_dataset(file, Path::new("u.vtu"));
    for base64 in [false, true] {
        // Valid: 12 bytes that fill the section exactly.
        let mut ok = words(&[12]);
        ok.extend_from_slice(&[0; 12]);
        let d = field(&undeclared_field_array("", &ok, base64)).unwrap();
        assert_eq!(d.field_data[0].values, vec![0.0; 3]);
        // Lengths beyond the bytes present, up to 2^64 − 1.
        for n in [16, 1 << 40, u64::MAX - 3, u64::MAX] {
            let mut p = words(&[n]);
            p.extend_from_slice(&[0; 12]);
            let e = field(&undeclared_field_array("", &p, base64))
                .unwrap_err()
                .to_string();
            // base64 text may hold 16 bytes' worth of characters; then it is cut short.
            let short = base64 && e.contains("base64 data needs");
            assert!(
                short || e.contains(&format!("data header says {n} bytes")),
                "{e}"
            );
        }
        // lz4 cannot expand beyond 255:1: a 1 TiB claim is refused before allocating.
        let blk = compress("vtkLZ4DataCompressor", &[0u8; 12]);
        let mut p = words(&[1, 1 << 40, 1 << 40, blk.len() as u64]);
        p.extend_from_slice(&blk);
        let lz4 = r#"compressor="vtkLZ4DataCompressor""#;
        let e = field(&undeclared_field_array(lz4, &p, base64))
            .unwrap_err()
            .to_string();
        assert!(e.contains("cannot hold the 1099511627776 bytes"), "{e}");
        // A last block larger than the block size is a damaged header.
        let mut p = words(&[2, 12, 24, blk.len() as u64, blk.len() as u64]);
        p.extend_from_slice(&blk);
        p.extend_from_slice(&blk);
        let e = field(&undeclared_field_array(lz4, &p, base64))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("last block of 24 bytes is larger than the block size 12"),
            "{e}"
        );
        // A valid two-block array (12 + 12 bytes) with an undeclared size.
        let mut p = words(&[2, 12, 0, blk.len() as u64, blk.len() as u64]);
        p.extend_from_slice(&blk);
        p.extend_from_slice(&blk);
        let d = field(&undeclared_field_array(lz4, &p, base64)).unwrap();
        assert_eq!(d.field_data[0].values.len(), 6);
    }
}
