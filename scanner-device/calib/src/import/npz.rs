//! NumPy's `.npz` (`np.savez(file, mtx=…, dist=…)`, stored or, with `np.savez_compressed`,
//! deflated): a zip archive of `.npy` arrays, one per name. An `.npy` is the magic `\x93NUMPY`,
//! its version (1, 2 or 3), the header's length (2 bytes little-endian in version 1, 4 after),
//! the header — a Python dict literal with `descr` (the dtype, e.g. `<f8`), `fortran_order`
//! and `shape` — and the values. Only the camera's two arrays are read; others (each shot's
//! pose, pickled object arrays) are left alone. An `.npz` holds no image size: it is given.

use std::io::Read;

use super::{Format, ImportError, ImportOptions, Imported, MAX_IMPORT_BYTES};

/// Most values of one array read (a camera file's arrays have at most 14).
const MAX_VALUES: usize = 4096;

/// An `.npz`'s bytes (`name`: its path, for errors): its camera.
pub(super) fn import(
    name: &str,
    bytes: &[u8],
    opts: &ImportOptions,
) -> Result<Imported, ImportError> {
    let zip_error = |source| ImportError::Zip {
        path: name.to_string(),
        source,
    };
    let mut archive = zip::ZipArchive::new(std::io::Cursor::new(bytes)).map_err(zip_error)?;
    let arrays: Vec<String> = archive
        .file_names()
        .filter_map(Result::ok)
        .filter_map(|n| n.strip_suffix(".npy").map(str::to_string))
        .collect();
    let mut read = |key: &str| -> Result<(usize, usize, Vec<f64>), ImportError> {
        let mut entry = archive.by_name(&format!("{key}.npy")).map_err(zip_error)?;
        if entry.size() > MAX_IMPORT_BYTES {
            return Err(unreadable(
                name,
                format!(
                    "{key}.npy holds {} bytes, more than {MAX_IMPORT_BYTES}",
                    entry.size()
                ),
            ));
        }
        let mut data = Vec::new();
        entry
            .by_ref()
            .take(MAX_IMPORT_BYTES)
            .read_to_end(&mut data)
            .map_err(|source| ImportError::Io {
                path: format!("{name} ({key}.npy)"),
                source,
            })?;
        npy(name, key, &data)
    };
    // the two arrays the camera needs, read first so that a broken one is named
    let mut found = Vec::new();
    for keys in [&super::CAMERA_KEYS[..], &super::DISTORTION_KEYS[..]] {
        if let Some(k) = super::first_of(keys, |k| arrays.iter().any(|a| a == k)) {
            found.push((k.to_string(), read(k)?));
        }
    }
    let get = |k: &str| found.iter().find(|(n, _)| n == k).map(|(_, v)| v.clone());
    let (k, d) = super::camera_arrays(name, arrays.iter().map(String::as_str), get)?;
    let camera = super::camera(name, k, &d)?;
    super::camera_only(name, Format::NumPy, &camera, None, opts)
}

fn unreadable(path: &str, why: String) -> ImportError {
    ImportError::Unreadable {
        path: path.to_string(),
        why,
    }
}

/// An `.npy`'s values as `f64` with its shape as rows × columns (a vector is one row).
fn npy(path: &str, key: &str, b: &[u8]) -> Result<(usize, usize, Vec<f64>), ImportError> {
    let bad = |why: String| unreadable(path, format!("{key}.npy: {why}"));
    if b.len() < 10 || &b[..6] != b"\x93NUMPY" {
        return Err(bad("not an .npy array (no \\x93NUMPY magic)".into()));
    }
    let (len, at): (usize, usize) = match b[6] {
        1 => (usize::from(u16::from_le_bytes([b[8], b[9]])), 10),
        2 | 3 if b.len() >= 12 => (u32::from_le_bytes([b[8], b[9], b[10], b[11]]) as usize, 12),
        v => return Err(bad(format!("format version {v}, not 1, 2 or 3"))),
    };
    let header = b
        .get(at..at.saturating_add(len))
        .ok_or_else(|| bad(format!("a header of {len} bytes in {} bytes", b.len())))?;
    let header = String::from_utf8_lossy(header);
    let field = |name: &str| -> Option<&str> {
        let i = header.find(&format!("'{name}'"))? + name.len() + 2;
        Some(header[i..].trim_start().strip_prefix(':')?.trim_start())
    };
    let descr = field("descr")
        .and_then(|v| v.strip_prefix('\''))
        .and_then(|v| v.split('\'').next())
        .ok_or_else(|| bad("no 'descr' in its header".into()))?;
    let fortran = field("fortran_order").is_some_and(|v| v.starts_with("True"));
    let shape_text = field("shape")
        .and_then(|v| v.strip_prefix('('))
        .and_then(|v| v.split(')').next())
        .ok_or_else(|| bad("no 'shape' in its header".into()))?;
    let shape: Vec<usize> = shape_text
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.trim_end_matches('L').parse::<usize>())
        .collect::<Result<_, _>>()
        .map_err(|_| bad(format!("shape ({shape_text}) is not a list of counts")))?;
    let (rows, cols) = match shape[..] {
        [] => (1, 1),
        [n] => (1, n),
        [r, c] => (r, c),
        _ => {
            return Err(bad(format!(
                "shape ({shape_text}): more than two dimensions"
            )));
        }
    };
    let count = rows
        .checked_mul(cols)
        .filter(|&n| n <= MAX_VALUES)
        .ok_or_else(|| {
            bad(format!(
                "shape ({shape_text}): more than {MAX_VALUES} values"
            ))
        })?;
    let (little, kind, size) = match descr.as_bytes() {
        [e @ (b'<' | b'>' | b'|' | b'='), k, s] => (*e != b'>', *k, *s),
        _ => return Err(bad(format!("dtype {descr:?} is not a number's"))),
    };
    let size = match size {
        b'1'..=b'9' => usize::from(size - b'0'),
        _ => return Err(bad(format!("dtype {descr:?} is not a number's"))),
    };
    let value: fn([u8; 8], bool) -> f64 = match (kind, size) {
        (b'f', 8) => |w, le| {
            if le {
                f64::from_le_bytes(w)
            } else {
                f64::from_be_bytes(w)
            }
        },
        (b'f', 4) => |w, le| {
            let w = [w[0], w[1], w[2], w[3]];
            f64::from(if le {
                f32::from_le_bytes(w)
            } else {
                f32::from_be_bytes(w)
            })
        },
        (b'i', 8) => |w, le| {
            (if le {
                i64::from_le_bytes(w)
            } else {
                i64::from_be_bytes(w)
            }) as f64
        },
        (b'i', 4) => |w, le| {
            let w = [w[0], w[1], w[2], w[3]];
            f64::from(if le {
                i32::from_le_bytes(w)
            } else {
                i32::from_be_bytes(w)
            })
        },
        _ => {
            return Err(bad(format!(
                "dtype {descr:?}: only floats (f4, f8) and integers (i4, i8) are read"
            )));
        }
    };
    let body = &b[at + len..];
    if body.len() < count * size {
        return Err(bad(format!(
            "{} bytes of values for {count} of {size} bytes",
            body.len()
        )));
    }
    let mut data: Vec<f64> = body
        .chunks_exact(size)
        .take(count)
        .map(|c| {
            let mut w = [0u8; 8];
            w[..size].copy_from_slice(c);
            value(w, little)
        })
        .collect();
    if fortran && rows > 1 && cols > 1 {
        // column by column: read back row by row
        data = (0..rows * cols)
            .map(|i| data[(i % cols) * rows + i / cols])
            .collect();
    }
    Ok((rows, cols, data))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An `.npy` of version 1 as NumPy's format description lays it out: the header padded
    /// with spaces and a newline to a multiple of 64 bytes.
    fn npy_bytes(descr: &str, fortran: bool, shape: &str, values: &[u8]) -> Vec<u8> {
        let mut header = format!(
            "{{'descr': '{descr}', 'fortran_order': {}, 'shape': {shape}, }}",
            if fortran { "True" } else { "False" }
        );
        while (10 + header.len() + 1) % 64 != 0 {
            header.push(' ');
        }
        header.push('\n');
        let mut out = b"\x93NUMPY\x01\x00".to_vec();
        out.extend_from_slice(&(header.len() as u16).to_le_bytes());
        out.extend_from_slice(header.as_bytes());
        out.extend_from_slice(values);
        out
    }

    #[test]
    fn arrays_read_in_their_order_and_type() {
        let m: Vec<u8> = (1..=9).flat_map(|v| f64::from(v).to_le_bytes()).collect();
        let (r, c, d) = npy("f", "mtx", &npy_bytes("<f8", false, "(3, 3)", &m)).unwrap();
        assert_eq!((r, c), (3, 3));
        assert_eq!(d, (1..=9).map(f64::from).collect::<Vec<_>>());
        // column by column: the same matrix read back row by row
        let (_, _, t) = npy("f", "mtx", &npy_bytes("<f8", true, "(3, 3)", &m)).unwrap();
        assert_eq!(t[1], 4.0);
        assert_eq!(t[3], 2.0);
        let f: Vec<u8> = [0.5f32, -0.25]
            .iter()
            .flat_map(|v| v.to_be_bytes())
            .collect();
        let (r, c, d) = npy("f", "dist", &npy_bytes(">f4", false, "(1, 2)", &f)).unwrap();
        assert_eq!((r, c, d), (1, 2, vec![0.5, -0.25]));
        let (r, c, _) = npy("f", "dist", &npy_bytes("<f4", false, "(2,)", &[0; 8])).unwrap();
        assert_eq!((r, c), (1, 2));
    }

    #[test]
    fn broken_arrays_are_refused_by_name() {
        let kinds = [
            npy("f", "k", b"not numpy at all"),
            npy("f", "k", &npy_bytes("<c16", false, "(3, 3)", &[0; 144])),
            npy("f", "k", &npy_bytes("<f8", false, "(3, 3)", &[0; 40])),
            npy("f", "k", &npy_bytes("<f8", false, "(3, 3, 3)", &[0; 216])),
            npy("f", "k", &npy_bytes("<f8", false, "(100000, 100000)", &[])),
            npy("f", "k", &npy_bytes("|O", false, "(3,)", &[0; 24])),
        ];
        for k in kinds {
            assert!(matches!(k, Err(ImportError::Unreadable { .. })), "{k:?}");
        }
    }
}
