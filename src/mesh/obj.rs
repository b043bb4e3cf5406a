//! Wavefront OBJ surfaces, for a user who brings an organ's mesh (the rectum's and the pelvis's
//! surfaces for `Anatomy::from_meshes`, for instance): vertices (`v x y z`, an optional fourth
//! weight ignored) and faces (`f a b c ...` with `a`, `a/t`, `a//n` or `a/t/n` corners, indices
//! from 1 or negative from the end; polygons split into fans). Everything else (normals,
//! texture coordinates, groups, materials, comments) is skipped. Coordinates are multiplied by
//! `scale` to give metres (OBJ has no units: 0.001 for a file in millimetres).
//!
//! An error names the file and the line, and says what was expected.

use super::TriMesh;
use glam::Vec3;

/// Why an OBJ file could not be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ObjError {
    #[error("{file}, line {line}: {message}")]
    Line {
        file: String,
        line: usize,
        message: String,
    },
    #[error("{file}: {message}")]
    File { file: String, message: String },
}

/// Reads an OBJ text; `file` names it in errors.
pub fn parse(file: &str, text: &str, scale: f32) -> Result<TriMesh, ObjError> {
    if !(scale.is_finite() && scale > 0.0) {
        return Err(ObjError::File {
            file: file.to_string(),
            message: format!("the scale must be finite and > 0, got {scale}"),
        });
    }
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    let mut corners = Vec::new();
    for (k, raw) in text.lines().enumerate() {
        let line = k + 1;
        let err = |message: String| ObjError::Line {
            file: file.to_string(),
            line,
            message,
        };
        let text = raw.split('#').next().unwrap_or("").trim();
        let mut words = text.split_whitespace();
        match words.next() {
            Some("v") => {
                let mut p = [0.0f32; 3];
                for (c, slot) in p.iter_mut().enumerate() {
                    let w = words.next().ok_or_else(|| {
                        err(format!(
                            "a vertex needs x, y and z; coordinate {} is missing",
                            c + 1
                        ))
                    })?;
                    let v: f32 = w
                        .parse()
                        .map_err(|_| err(format!("'{w}' is not a number")))?;
                    if !v.is_finite() {
                        return Err(err(format!("coordinate '{w}' is not finite")));
                    }
                    *slot = v * scale;
                }
                positions.push(Vec3::from_array(p));
            }
            Some("f") => {
                corners.clear();
                for w in words {
                    let index = w.split('/').next().unwrap_or("");
                    let i: i64 = index.parse().map_err(|_| {
                        err(format!(
                            "face corner '{w}' does not start with a vertex index"
                        ))
                    })?;
                    let n = positions.len() as i64;
                    let at = match i {
                        0 => return Err(err("vertex index 0 (OBJ counts from 1)".to_string())),
                        i if i > 0 => i - 1,
                        i => n + i,
                    };
                    if !(0..n).contains(&at) {
                        return Err(err(format!(
                            "vertex {i} does not exist (there are {n} vertices so far)"
                        )));
                    }
                    corners.push(at as u32);
                }
                if corners.len() < 3 {
                    return Err(err(format!(
                        "a face needs at least 3 corners, got {}",
                        corners.len()
                    )));
                }
                for k in 1..corners.len() - 1 {
                    triangles.push([corners[0], corners[k], corners[k + 1]]);
                }
            }
            _ => {}
        }
    }
    if triangles.is_empty() {
        return Err(ObjError::File {
            file: file.to_string(),
            message: "no faces ('f' lines)".to_string(),
        });
    }
    Ok(TriMesh {
        positions,
        triangles,
    })
}

/// Reads an OBJ file from disk.
pub fn load(path: &std::path::Path, scale: f32) -> Result<TriMesh, ObjError> {
    let file = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| ObjError::File {
        file: file.clone(),
        message: format!("cannot read it: {e}"),
    })?;
    parse(&file, &text, scale)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_square_in_millimetres_reads_as_two_triangles_in_metres() {
        let text = "# a unit square\nv 0 0 0\nv 10 0 0\nv 10 10 0\nv 0 10 0 1.0\nvn 0 0 1\n\
                    f 1//1 2//1 3//1 4//1\n";
        let m = parse("square.obj", text, 1e-3).expect("square");
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        assert!(m.positions[2].distance(Vec3::new(0.01, 0.01, 0.0)) < 1e-8);
        assert!((m.area() - 1e-4).abs() < 1e-9, "{}", m.area());
    }

    #[test]
    fn negative_indices_count_back_from_the_last_vertex() {
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3/1 -2/2 -1/3\n";
        let m = parse("neg.obj", text, 1.0).expect("triangle");
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
    }

    #[test]
    fn a_generated_tube_round_trips() {
        let t = crate::mesh::tube(&crate::mesh::TubeSpec {
            path: vec![Vec3::ZERO, Vec3::new(0.1, 0.0, 0.0)],
            radius_m: 0.02,
            segments: 12,
            rings: 5,
        });
        let mut text = String::new();
        for p in &t.positions {
            text.push_str(&format!("v {} {} {}\n", p.x * 1e3, p.y * 1e3, p.z * 1e3));
        }
        for f in &t.triangles {
            text.push_str(&format!("f {} {} {}\n", f[0] + 1, f[1] + 1, f[2] + 1));
        }
        let m = parse("tube.obj", &text, 1e-3).expect("tube");
        assert_eq!(m.triangles, t.triangles);
        let worst = m
            .positions
            .iter()
            .zip(&t.positions)
            .map(|(a, b)| a.distance(*b))
            .fold(0.0f32, f32::max);
        assert!(worst < 1e-6, "{worst}");
        assert!((m.volume() - t.volume()).abs() < 1e-3 * t.volume());
    }

    #[test]
    fn bad_lines_are_named() {
        let cases = [
            ("v 1 2\nf 1 1 1\n", 1, "coordinate 3 is missing"),
            ("v 1 2 x\n", 1, "'x' is not a number"),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n",
                4,
                "vertex 4 does not exist",
            ),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", 4, "index 0"),
            ("v 0 0 0\nv 1 0 0\nf 1 2\n", 3, "at least 3 corners"),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf a b c\n",
                4,
                "does not start with a vertex index",
            ),
            ("v inf 0 0\n", 1, "not finite"),
        ];
        for (text, line, what) in cases {
            match parse("bad.obj", text, 1.0) {
                Err(ObjError::Line {
                    line: l,
                    message,
                    file,
                }) => {
                    assert_eq!((l, file.as_str()), (line, "bad.obj"), "{text:?}");
                    assert!(message.contains(what), "{message} / {what}");
                }
                other => panic!("{text:?}: {other:?}"),
            }
        }
        assert!(matches!(
            parse("empty.obj", "v 0 0 0\n", 1.0),
            Err(ObjError::File { .. })
        ));
        assert!(matches!(
            parse("s.obj", "f 1 2 3\n", 0.0),
            Err(ObjError::File { .. })
        ));
    }
}
