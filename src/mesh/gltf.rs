//! glTF 2.0 surfaces (`.glb`, or `.gltf` with its buffers in `data:` URIs or files beside it),
//! for a user who brings an organ's mesh. Every triangle primitive of every mesh is read
//! (`POSITION` as float triples, indices as unsigned bytes, shorts or ints, or none) and joined
//! into one surface; node transforms are not applied (the mesh's own coordinates). glTF's unit
//! is the metre; `scale` multiplies the coordinates all the same.
//!
//! An error names the file and the JSON path (or the byte offset) and says what was expected.

use super::TriMesh;
use glam::Vec3;
use serde_json::Value;

/// Why a glTF file could not be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{file}: {at}: {message}")]
pub struct GltfError {
    pub file: String,
    /// Where: a JSON path (`meshes[0].primitives[1].indices`) or a part of the file.
    pub at: String,
    pub message: String,
}

const GLB_MAGIC: u32 = 0x4654_6C67;
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;
const TRIANGLES: u64 = 4;

struct Reader<'a> {
    file: &'a str,
    json: Value,
    buffers: Vec<Vec<u8>>,
}

impl Reader<'_> {
    fn err(&self, at: impl Into<String>, message: impl Into<String>) -> GltfError {
        GltfError {
            file: self.file.to_string(),
            at: at.into(),
            message: message.into(),
        }
    }

    fn uint(&self, v: &Value, at: &str) -> Result<u64, GltfError> {
        v.as_u64()
            .ok_or_else(|| self.err(at, "expected a whole number >= 0"))
    }

    fn get<'v>(&self, v: &'v Value, key: &str, at: &str) -> Result<&'v Value, GltfError> {
        v.get(key)
            .ok_or_else(|| self.err(format!("{at}.{key}"), "missing"))
    }

    /// Accessor `index`'s elements as bytes with their layout: (data, count, stride, component
    /// type, components).
    fn accessor(
        &self,
        index: u64,
        at: &str,
    ) -> Result<(&[u8], usize, usize, u64, usize), GltfError> {
        let a = self
            .json
            .get("accessors")
            .and_then(|v| v.get(index as usize))
            .ok_or_else(|| self.err(at, format!("accessor {index} does not exist")))?;
        let here = format!("accessors[{index}]");
        let count = self.uint(self.get(a, "count", &here)?, &format!("{here}.count"))? as usize;
        let ctype = self.uint(
            self.get(a, "componentType", &here)?,
            &format!("{here}.componentType"),
        )?;
        let kind = self
            .get(a, "type", &here)?
            .as_str()
            .ok_or_else(|| self.err(format!("{here}.type"), "expected a string"))?;
        let comps = match kind {
            "SCALAR" => 1,
            "VEC2" => 2,
            "VEC3" => 3,
            "VEC4" => 4,
            other => return Err(self.err(format!("{here}.type"), format!("'{other}' is not read"))),
        };
        let size = match ctype {
            5121 => 1,
            5123 => 2,
            5125 | 5126 => 4,
            other => {
                return Err(self.err(
                    format!("{here}.componentType"),
                    format!("{other} is not read (5121, 5123, 5125 or 5126)"),
                ));
            }
        };
        let view_index = self.uint(
            self.get(a, "bufferView", &here)?,
            &format!("{here}.bufferView"),
        )?;
        let offset = a.get("byteOffset").and_then(Value::as_u64).unwrap_or(0) as usize;
        let view = self
            .json
            .get("bufferViews")
            .and_then(|v| v.get(view_index as usize))
            .ok_or_else(|| {
                self.err(
                    format!("{here}.bufferView"),
                    format!("buffer view {view_index} does not exist"),
                )
            })?;
        let vat = format!("bufferViews[{view_index}]");
        let buffer = self.uint(self.get(view, "buffer", &vat)?, &format!("{vat}.buffer"))? as usize;
        let data = self.buffers.get(buffer).ok_or_else(|| {
            self.err(
                format!("{vat}.buffer"),
                format!("buffer {buffer} does not exist"),
            )
        })?;
        let view_offset = view.get("byteOffset").and_then(Value::as_u64).unwrap_or(0) as usize;
        let view_len = self.uint(
            self.get(view, "byteLength", &vat)?,
            &format!("{vat}.byteLength"),
        )? as usize;
        let stride = view
            .get("byteStride")
            .and_then(Value::as_u64)
            .map_or(size * comps, |s| s as usize);
        let bytes = data
            .get(view_offset..view_offset.saturating_add(view_len))
            .ok_or_else(|| {
                self.err(
                    &vat,
                    format!(
                        "runs past the end of buffer {buffer} ({} bytes)",
                        data.len()
                    ),
                )
            })?;
        let need = if count == 0 {
            0
        } else {
            offset + stride * (count - 1) + size * comps
        };
        if need > bytes.len() || stride < size * comps {
            return Err(self.err(
                &here,
                format!(
                    "{count} elements need {need} bytes of a {}-byte view",
                    bytes.len()
                ),
            ));
        }
        Ok((&bytes[offset..], count, stride, ctype, comps))
    }
}

/// The array under `key` (none: empty).
fn array<'v>(v: &'v Value, key: &str) -> &'v [Value] {
    v.get(key)
        .and_then(Value::as_array)
        .map_or(&[], Vec::as_slice)
}

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    b.get(at..at + 4)
        .map(|s| u32::from_le_bytes([s[0], s[1], s[2], s[3]]))
}

/// Decodes standard base64 (padding optional).
fn base64(text: &str) -> Option<Vec<u8>> {
    let value = |c: u8| -> Option<u32> {
        Some(match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => return None,
        } as u32)
    };
    let clean: Vec<u8> = text.bytes().filter(|&c| c != b'=').collect();
    let mut out = Vec::with_capacity(clean.len() * 3 / 4);
    for chunk in clean.chunks(4) {
        let mut acc = 0u32;
        for (k, &c) in chunk.iter().enumerate() {
            acc |= value(c)? << (18 - 6 * k);
        }
        let bytes = acc.to_be_bytes();
        out.extend_from_slice(&bytes[1..chunk.len().max(1)]);
    }
    Some(out)
}

/// Reads a glTF file's bytes (`.glb`, or `.gltf` JSON); `file` names it in errors, and
/// external buffers are looked for beside `dir`.
pub fn parse(
    file: &str,
    bytes: &[u8],
    dir: Option<&std::path::Path>,
    scale: f32,
) -> Result<TriMesh, GltfError> {
    let fail = |at: &str, message: String| GltfError {
        file: file.to_string(),
        at: at.to_string(),
        message,
    };
    if !(scale.is_finite() && scale > 0.0) {
        return Err(fail(
            "scale",
            format!("must be finite and > 0, got {scale}"),
        ));
    }
    let (json_bytes, bin) = if u32_at(bytes, 0) == Some(GLB_MAGIC) {
        let len = u32_at(bytes, 12).ok_or_else(|| fail("header", "cut short".into()))? as usize;
        if u32_at(bytes, 16) != Some(CHUNK_JSON) || bytes.len() < 20 + len {
            return Err(fail("chunk 0", "expected the JSON chunk".into()));
        }
        let json = &bytes[20..20 + len];
        let rest = 20 + len;
        let bin = match (u32_at(bytes, rest), u32_at(bytes, rest + 4)) {
            (Some(n), Some(CHUNK_BIN)) => bytes
                .get(rest + 8..rest + 8 + n as usize)
                .map(<[u8]>::to_vec),
            _ => None,
        };
        (json, bin)
    } else {
        (bytes, None)
    };
    let json: Value = serde_json::from_slice(json_bytes)
        .map_err(|e| fail("JSON", format!("not valid JSON: {e}")))?;
    let mut reader = Reader {
        file,
        json,
        buffers: Vec::new(),
    };
    let json = std::mem::take(&mut reader.json);
    let mut bin = bin;
    for (k, b) in array(&json, "buffers").iter().enumerate() {
        let at = format!("buffers[{k}]");
        let data = match b.get("uri").and_then(Value::as_str) {
            None => bin
                .take()
                .ok_or_else(|| reader.err(&at, "no uri and no binary chunk"))?,
            Some(uri) if uri.starts_with("data:") => {
                let payload = uri.split_once(";base64,").map(|(_, p)| p).ok_or_else(|| {
                    reader.err(format!("{at}.uri"), "only base64 data URIs are read")
                })?;
                base64(payload).ok_or_else(|| reader.err(format!("{at}.uri"), "bad base64"))?
            }
            Some(uri) => {
                let path = dir.map_or_else(|| uri.into(), |d| d.join(uri));
                std::fs::read(&path).map_err(|e| {
                    reader.err(
                        format!("{at}.uri"),
                        format!("cannot read {}: {e}", path.display()),
                    )
                })?
            }
        };
        reader.buffers.push(data);
    }
    let mut positions: Vec<Vec3> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    reader.json = json;
    for (mi, mesh) in array(&reader.json, "meshes").iter().enumerate() {
        for (pi, prim) in array(mesh, "primitives").iter().enumerate() {
            let at = format!("meshes[{mi}].primitives[{pi}]");
            let mode = prim
                .get("mode")
                .and_then(Value::as_u64)
                .unwrap_or(TRIANGLES);
            if mode != TRIANGLES {
                return Err(
                    reader.err(format!("{at}.mode"), format!("{mode} is not triangles (4)"))
                );
            }
            let pos = prim
                .get("attributes")
                .and_then(|a| a.get("POSITION"))
                .and_then(Value::as_u64)
                .ok_or_else(|| reader.err(format!("{at}.attributes.POSITION"), "missing"))?;
            let (data, count, stride, ctype, comps) =
                reader.accessor(pos, &format!("{at}.attributes.POSITION"))?;
            if ctype != 5126 || comps != 3 {
                return Err(reader.err(format!("accessors[{pos}]"), "POSITION must be float VEC3"));
            }
            let base = positions.len() as u32;
            for k in 0..count {
                let f = |c: usize| {
                    let o = k * stride + 4 * c;
                    f32::from_le_bytes([data[o], data[o + 1], data[o + 2], data[o + 3]])
                };
                let p = Vec3::new(f(0), f(1), f(2));
                if !p.is_finite() {
                    return Err(reader.err(
                        format!("accessors[{pos}]"),
                        format!("position {k} is not finite"),
                    ));
                }
                positions.push(p * scale);
            }
            let indices: Vec<u32> = match prim.get("indices").and_then(Value::as_u64) {
                None => (0..count as u32).collect(),
                Some(ix) => {
                    let (d, n, stride, ctype, comps) =
                        reader.accessor(ix, &format!("{at}.indices"))?;
                    if comps != 1 || ctype == 5126 {
                        return Err(reader.err(
                            format!("accessors[{ix}]"),
                            "indices must be unsigned scalars",
                        ));
                    }
                    (0..n)
                        .map(|k| {
                            let o = k * stride;
                            match ctype {
                                5121 => u32::from(d[o]),
                                5123 => u32::from(u16::from_le_bytes([d[o], d[o + 1]])),
                                _ => u32::from_le_bytes([d[o], d[o + 1], d[o + 2], d[o + 3]]),
                            }
                        })
                        .collect()
                }
            };
            if !indices.len().is_multiple_of(3) {
                return Err(reader.err(
                    format!("{at}.indices"),
                    format!("{} indices is not whole triangles", indices.len()),
                ));
            }
            for t in indices.chunks(3) {
                if let Some(&bad) = t.iter().find(|&&i| i as usize >= count) {
                    return Err(reader.err(
                        format!("{at}.indices"),
                        format!("vertex {bad} does not exist ({count} vertices)"),
                    ));
                }
                triangles.push([base + t[0], base + t[1], base + t[2]]);
            }
        }
    }
    if triangles.is_empty() {
        return Err(fail("meshes", "no triangles".into()));
    }
    Ok(TriMesh {
        positions,
        triangles,
    })
}

/// Reads a `.glb` or `.gltf` file from disk.
pub fn load(path: &std::path::Path, scale: f32) -> Result<TriMesh, GltfError> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| GltfError {
        file: file.clone(),
        at: "file".into(),
        message: format!("cannot read it: {e}"),
    })?;
    parse(&file, &bytes, path.parent(), scale)
}

#[cfg(test)]
#[path = "gltf_tests.rs"]
mod tests;
