use super::*;
use crate::mesh::{TubeSpec, tube};

fn sample() -> TriMesh {
    tube(&TubeSpec {
        path: vec![Vec3::ZERO, Vec3::new(0.1, 0.0, 0.0)],
        radius_m: 0.02,
        segments: 10,
        rings: 4,
    })
}

/// The JSON and binary buffer of `m` as one primitive with u16 or u32 indices.
fn pieces(m: &TriMesh, wide: bool, uri: Option<String>) -> (String, Vec<u8>) {
    let mut bin = Vec::new();
    for p in &m.positions {
        for c in p.to_array() {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    let pos_len = bin.len();
    for t in &m.triangles {
        for &i in t {
            if wide {
                bin.extend_from_slice(&i.to_le_bytes());
            } else {
                bin.extend_from_slice(&(i as u16).to_le_bytes());
            }
        }
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let idx_len = bin.len() - pos_len;
    let uri = uri.map_or(String::new(), |u| format!(r#","uri":"{u}""#));
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"buffers":[{{"byteLength":{}{uri}}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":{pos_len}}},
                       {{"buffer":0,"byteOffset":{pos_len},"byteLength":{idx_len}}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":{},"type":"VEC3"}},
                     {{"bufferView":1,"componentType":{},"count":{},"type":"SCALAR"}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1,"mode":4}}]}}]}}"#,
        bin.len(),
        m.positions.len(),
        if wide { 5125 } else { 5123 },
        3 * m.triangles.len(),
    );
    (json, bin)
}

fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut j = json.as_bytes().to_vec();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    let mut out = Vec::new();
    out.extend_from_slice(&GLB_MAGIC.to_le_bytes());
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&((12 + 8 + j.len() + 8 + bin.len()) as u32).to_le_bytes());
    out.extend_from_slice(&(j.len() as u32).to_le_bytes());
    out.extend_from_slice(&CHUNK_JSON.to_le_bytes());
    out.extend_from_slice(&j);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(&CHUNK_BIN.to_le_bytes());
    out.extend_from_slice(bin);
    out
}

fn encode64(b: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in b.chunks(3) {
        let n = (u32::from(c[0]) << 16)
            | (u32::from(*c.get(1).unwrap_or(&0)) << 8)
            | u32::from(*c.get(2).unwrap_or(&0));
        for k in 0..4 {
            if k <= c.len() {
                s.push(A[((n >> (18 - 6 * k)) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

#[test]
fn a_glb_tube_reads_back_exactly() {
    let m = sample();
    for wide in [false, true] {
        let (json, bin) = pieces(&m, wide, None);
        let back = parse("tube.glb", &glb(&json, &bin), None, 1.0).expect("glb");
        assert_eq!(back, m);
    }
}

#[test]
fn a_gltf_with_a_data_uri_reads_back_and_scales() {
    let m = sample();
    let (_, bin) = pieces(&m, true, None);
    let uri = format!("data:application/octet-stream;base64,{}", encode64(&bin));
    let (json, _) = pieces(&m, true, Some(uri));
    let back = parse("tube.gltf", json.as_bytes(), None, 2.0).expect("gltf");
    assert_eq!(back.triangles, m.triangles);
    for (a, b) in back.positions.iter().zip(&m.positions) {
        assert!(a.distance(*b * 2.0) < 1e-7);
    }
}

#[test]
fn bad_files_say_where() {
    let m = sample();
    let (json, bin) = pieces(&m, false, None);
    let check = |json: String, bin: &[u8], at: &str, what: &str| {
        let e = parse("bad.glb", &glb(&json, bin), None, 1.0).expect_err("refused");
        assert!(e.at.contains(at), "{e}");
        assert!(e.message.contains(what), "{e}");
        assert!(e.to_string().starts_with("bad.glb: "), "{e}");
    };
    check(
        json.replace(r#""mode":4"#, r#""mode":1"#),
        &bin,
        "mode",
        "not triangles",
    );
    check(
        json.replace(r#""POSITION":0"#, r#""NORMAL":0"#),
        &bin,
        "POSITION",
        "missing",
    );
    check(
        json.clone(),
        &bin[..bin.len() / 2],
        "bufferViews[",
        "runs past the end",
    );
    let mut broken = bin.clone();
    let pos_len = 12 * m.positions.len();
    broken[pos_len..pos_len + 2].copy_from_slice(&999u16.to_le_bytes());
    check(json, &broken, "indices", "vertex 999 does not exist");
    let e = parse("x.gltf", b"{not json", None, 1.0).expect_err("refused");
    assert!(e.message.contains("not valid JSON"), "{e}");
}
