//! OpenCV's FileStorage files (`cv::FileStorage`, as its calibration samples write them): a
//! camera matrix and distortion coefficients, each an `opencv-matrix` (`rows`, `cols`, `dt`,
//! `data` row by row) or a plain sequence, and the image size as `image_width` and
//! `image_height` (or `image_size: [w, h]`).
//!
//! YAML (`%YAML:1.0`): top-level `name: value` lines; a matrix is `name: !!opencv-matrix`
//! followed by its indented fields, its `data: [ … ]` over as many lines as it needs. XML:
//! `<opencv_storage>` holding `<name type_id="opencv-matrix">` with `<rows>`, `<cols>`,
//! `<dt>` and `<data>` (numbers separated by white space). Only the top level is read: nested
//! maps and lists of maps are skipped.

use super::{ImportError, ImportOptions, Imported};

/// Most values of one array read (a camera file's arrays have at most 14).
const MAX_VALUES: usize = 4096;

/// A top-level value: its text (a scalar) or its numbers (a matrix or a sequence) with its
/// shape.
#[derive(Debug, Clone, PartialEq)]
enum Node {
    Scalar(String),
    Array {
        rows: usize,
        cols: usize,
        data: Vec<f64>,
    },
}

/// An OpenCV FileStorage file's text (XML when `xml`): its camera.
pub(super) fn import(
    name: &str,
    text: &str,
    xml: bool,
    opts: &ImportOptions,
) -> Result<Imported, ImportError> {
    let nodes = if xml {
        parse_xml(name, text)
    } else {
        parse_yaml(name, text)
    }?;
    let get = |k: &str| {
        nodes
            .iter()
            .find(|(n, _)| n == k)
            .and_then(|(_, v)| match v {
                Node::Array { rows, cols, data } => Some((*rows, *cols, data.clone())),
                Node::Scalar(s) => s.parse::<f64>().ok().map(|v| (1, 1, vec![v])),
            })
    };
    let (k, d) = super::camera_arrays(name, nodes.iter().map(|(n, _)| n.as_str()), get)?;
    let camera = super::camera(name, k, &d)?;
    let scalar = |k: &str| {
        nodes
            .iter()
            .find(|(n, _)| n == k)
            .and_then(|(_, v)| match v {
                Node::Scalar(s) => s.trim().parse::<u32>().ok(),
                Node::Array { data, .. } if data.len() == 1 => whole(data[0]),
                Node::Array { .. } => None,
            })
    };
    let size = match (scalar("image_width"), scalar("image_height")) {
        (Some(w), Some(h)) => Some((w, h)),
        _ => ["image_size", "imageSize"]
            .iter()
            .find_map(|k| get(k))
            .filter(|(_, _, v)| v.len() == 2)
            .and_then(|(_, _, v)| Some((whole(v[0])?, whole(v[1])?))),
    };
    let format = if xml {
        super::Format::OpenCvXml
    } else {
        super::Format::OpenCvYaml
    };
    super::camera_only(name, format, &camera, size, opts)
}

/// `v` as a whole number of pixels.
fn whole(v: f64) -> Option<u32> {
    (v.fract() == 0.0 && (1.0..=f64::from(u32::MAX)).contains(&v)).then_some(v as u32)
}

/// The error of a file that does not parse: what is wrong, and where.
fn unreadable(path: &str, why: String) -> ImportError {
    ImportError::Unreadable {
        path: path.to_string(),
        why,
    }
}

/// Numbers separated by commas or white space (`at`: the value they belong to).
fn numbers(path: &str, text: &str, at: &str) -> Result<Vec<f64>, ImportError> {
    let mut out = Vec::new();
    for word in text
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|w| !w.is_empty())
    {
        if out.len() == MAX_VALUES {
            return Err(unreadable(
                path,
                format!("{at}: more than {MAX_VALUES} values"),
            ));
        }
        out.push(
            number(word)
                .ok_or_else(|| unreadable(path, format!("{at}: {word:?} is not a number")))?,
        );
    }
    Ok(out)
}

/// A number as OpenCV writes it (`1.`, `6.5e+002`, `.Nan`, `.Inf`, `-.Inf`).
fn number(word: &str) -> Option<f64> {
    match word {
        ".nan" | ".NaN" | ".Nan" | ".NAN" => Some(f64::NAN),
        ".inf" | ".Inf" | ".INF" => Some(f64::INFINITY),
        "-.inf" | "-.Inf" | "-.INF" => Some(f64::NEG_INFINITY),
        w => w.parse().ok(),
    }
}

/// A matrix from its fields (`rows`, `cols`, `data`), the data's count checked.
fn matrix(
    path: &str,
    name: &str,
    rows: Option<&str>,
    cols: Option<&str>,
    data: Option<&str>,
) -> Result<Node, ImportError> {
    let dim = |v: Option<&str>, what: &str| -> Result<usize, ImportError> {
        let v =
            v.ok_or_else(|| unreadable(path, format!("{name}: an opencv-matrix without {what}")))?;
        v.trim()
            .parse::<usize>()
            .ok()
            .filter(|&n| n <= MAX_VALUES)
            .ok_or_else(|| {
                unreadable(
                    path,
                    format!("{name}: {what} {:?} is not a count", v.trim()),
                )
            })
    };
    let (rows, cols) = (dim(rows, "rows")?, dim(cols, "cols")?);
    let text =
        data.ok_or_else(|| unreadable(path, format!("{name}: an opencv-matrix without data")))?;
    let data = numbers(path, text, name)?;
    if data.len() != rows * cols {
        return Err(unreadable(
            path,
            format!(
                "{name}: {rows}×{cols} but {} values in its data",
                data.len()
            ),
        ));
    }
    Ok(Node::Array { rows, cols, data })
}

/// The top-level values of an OpenCV YAML file, in its order.
fn parse_yaml(path: &str, text: &str) -> Result<Vec<(String, Node)>, ImportError> {
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let line = lines[i].trim_end();
        i += 1;
        if line.is_empty()
            || line.starts_with('%')
            || line.starts_with("---")
            || line.starts_with("...")
            || line.starts_with('#')
            || line.starts_with(char::is_whitespace)
            || line.starts_with('-')
        {
            continue;
        }
        let Some((key, value)) = line.split_once(':') else {
            return Err(unreadable(
                path,
                format!("line {i}: {line:?} is not `name: value`"),
            ));
        };
        let (key, value) = (key.trim().trim_matches('"').to_string(), value.trim());
        if value.starts_with("!!opencv-matrix") || value.is_empty() {
            // the indented fields that follow
            let mut fields: Vec<(String, String)> = Vec::new();
            while i < lines.len() && lines[i].starts_with(char::is_whitespace) {
                let l = lines[i].trim();
                i += 1;
                let Some((f, v)) = l.split_once(':') else {
                    // a continuation of the last field's value (`data` over several lines)
                    if let Some(last) = fields.last_mut() {
                        last.1.push(' ');
                        last.1.push_str(l);
                    }
                    continue;
                };
                fields.push((f.trim().to_string(), v.trim().to_string()));
            }
            if !value.starts_with("!!opencv-matrix") {
                // a nested map of another kind: not read
                continue;
            }
            let field = |n: &str| fields.iter().find(|(f, _)| f == n).map(|(_, v)| v.as_str());
            let data =
                field("data").map(|d| d.trim().trim_start_matches('[').trim_end_matches(']'));
            out.push((
                key.clone(),
                matrix(path, &key, field("rows"), field("cols"), data)?,
            ));
        } else if let Some(rest) = value.strip_prefix('[') {
            // a sequence, over as many lines as it takes
            let mut body = rest.to_string();
            while !body.contains(']') {
                let Some(l) = lines.get(i) else {
                    return Err(unreadable(
                        path,
                        format!("{key}: a sequence without its closing `]`"),
                    ));
                };
                i += 1;
                body.push(' ');
                body.push_str(l.trim());
            }
            let body = &body[..body.find(']').unwrap_or(body.len())];
            let data = numbers(path, body, &key)?;
            out.push((
                key,
                Node::Array {
                    rows: 1,
                    cols: data.len(),
                    data,
                },
            ));
        } else {
            out.push((key, Node::Scalar(value.trim_matches('"').to_string())));
        }
    }
    Ok(out)
}

/// The top-level values of an OpenCV XML file (the children of `<opencv_storage>`), in its
/// order.
fn parse_xml(path: &str, text: &str) -> Result<Vec<(String, Node)>, ImportError> {
    let bad = |why: &str| unreadable(path, why.to_string());
    let start = text
        .find("<opencv_storage>")
        .ok_or_else(|| bad("no <opencv_storage> element"))?
        + "<opencv_storage>".len();
    let end = text[start..]
        .find("</opencv_storage>")
        .ok_or_else(|| bad("no </opencv_storage> closing its element"))?
        + start;
    let mut body = &text[start..end];
    let mut out = Vec::new();
    while let Some(open) = body.find('<') {
        body = &body[open..];
        if body.starts_with("<!--") {
            let close = body
                .find("-->")
                .ok_or_else(|| bad("a comment that does not end"))?;
            body = &body[close + 3..];
            continue;
        }
        let tag_end = body
            .find('>')
            .ok_or_else(|| bad("a tag that does not end"))?;
        let tag = &body[1..tag_end];
        let name = tag
            .split_whitespace()
            .next()
            .filter(|n| !n.starts_with('/'))
            .ok_or_else(|| unreadable(path, format!("an unexpected tag <{tag}>")))?
            .to_string();
        if tag.ends_with('/') {
            body = &body[tag_end + 1..];
            continue;
        }
        let closing = format!("</{name}>");
        let content_end = body
            .find(&closing)
            .ok_or_else(|| unreadable(path, format!("<{name}> is not closed")))?;
        let content = &body[tag_end + 1..content_end];
        body = &body[content_end + closing.len()..];
        let child = |n: &str| -> Option<&str> {
            let open = format!("<{n}>");
            let a = content.find(&open)? + open.len();
            let b = content[a..].find(&format!("</{n}>"))? + a;
            Some(&content[a..b])
        };
        if tag.contains("opencv-matrix") {
            out.push((
                name.clone(),
                matrix(path, &name, child("rows"), child("cols"), child("data"))?,
            ));
        } else if content.contains('<') {
            // a nested map or sequence of another kind: not read
            continue;
        } else {
            let words: Vec<&str> = content.split_whitespace().collect();
            if words.len() > 1 {
                let data = numbers(path, content, &name)?;
                out.push((
                    name,
                    Node::Array {
                        rows: 1,
                        cols: data.len(),
                        data,
                    },
                ));
            } else {
                out.push((
                    name,
                    Node::Scalar(content.trim().trim_matches('"').to_string()),
                ));
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// As OpenCV's calibration sample writes it (`samples/cpp/calibration.cpp`), the older
    /// three-digit exponents included.
    const YAML: &str = "%YAML:1.0
---
calibration_time: \"Wed 08 Dec 2010 05:26:12 PM\"
image_width: 640
image_height: 480
board_width: 9
board_height: 6
square_size: 1.
flags: 0
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 6.5746697944293521e+002, 0., 3.1950000000000000e+002, 0.,
       6.5746697944293521e+002, 2.3950000000000000e+002, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 5
   cols: 1
   dt: d
   data: [ -4.1802327176423804e-001, 5.0715244063187526e-001, 0., 0.,
       -5.7843597214487474e-001 ]
avg_reprojection_error: 3.9411422032695307e-001
";

    #[test]
    fn yaml_as_opencv_writes_it() {
        let nodes = parse_yaml("cam.yml", YAML).unwrap();
        let get = |k: &str| nodes.iter().find(|(n, _)| n == k).map(|(_, v)| v.clone());
        assert_eq!(get("image_width"), Some(Node::Scalar("640".into())));
        let Some(Node::Array { rows, cols, data }) = get("camera_matrix") else {
            panic!("{nodes:?}")
        };
        assert_eq!((rows, cols), (3, 3));
        assert!((data[0] - 657.466_979_442_935_2).abs() < 1e-9 && data[8] == 1.0);
        let Some(Node::Array { rows, cols, data }) = get("distortion_coefficients") else {
            panic!("{nodes:?}")
        };
        assert_eq!((rows, cols, data.len()), (5, 1, 5));
        assert!((data[4] + 0.578_435_972_144_874_7).abs() < 1e-12);
        let imported = import("cam.yml", YAML, false, &ImportOptions::default()).unwrap();
        let c = &imported.file.camera;
        assert_eq!(
            (imported.file.image.width, imported.file.image.height),
            (640, 480)
        );
        assert!((c.fx - 657.466_979_442_935_2).abs() < 1e-9 && (c.cy - 239.5).abs() < 1e-9);
        assert!((c.k1 + 0.418_023_271_764_238).abs() < 1e-12);
    }

    #[test]
    fn xml_as_opencv_writes_it() {
        let xml = "<?xml version=\"1.0\"?>
<opencv_storage>
<image_width>640</image_width>
<image_height>480</image_height>
<!-- a comment -->
<camera_matrix type_id=\"opencv-matrix\">
  <rows>3</rows>
  <cols>3</cols>
  <dt>d</dt>
  <data>
    6.5746697944293521e+02 0. 3.1950000000000000e+02 0.
    6.5746697944293521e+02 2.3950000000000000e+02 0. 0. 1.</data></camera_matrix>
<distortion_coefficients type_id=\"opencv-matrix\">
  <rows>1</rows>
  <cols>5</cols>
  <dt>d</dt>
  <data>
    -4.1802327176423804e-01 5.0715244063187526e-01 0. 0.
    -5.7843597214487474e-01</data></distortion_coefficients>
</opencv_storage>
";
        let imported = import("cam.xml", xml, true, &ImportOptions::default()).unwrap();
        let c = &imported.file.camera;
        assert!((c.fx - 657.466_979_442_935_2).abs() < 1e-9);
        assert!((c.k3 + 0.578_435_972_144_874_7).abs() < 1e-12);
        assert_eq!(imported.file.image.width, 640);
    }

    #[test]
    fn broken_files_name_what_is_wrong() {
        let short_data = YAML.replace("0., 0., 1. ]", "0., 0. ]");
        let e = import("cam.yml", &short_data, false, &ImportOptions::default()).unwrap_err();
        assert!(matches!(e, ImportError::Unreadable { .. }), "{e:?}");
        let no_size = YAML
            .replace("image_width: 640\n", "")
            .replace("image_height: 480\n", "");
        let e = import("cam.yml", &no_size, false, &ImportOptions::default()).unwrap_err();
        assert!(matches!(e, ImportError::NoSize { .. }), "{e:?}");
        let sized = ImportOptions {
            size: Some((640, 480)),
            ..ImportOptions::default()
        };
        assert!(import("cam.yml", &no_size, false, &sized).is_ok());
        let other = ImportOptions {
            size: Some((1280, 960)),
            ..ImportOptions::default()
        };
        let e = import("cam.yml", YAML, false, &other).unwrap_err();
        assert!(matches!(e, ImportError::Invalid { .. }), "{e:?}");
        let no_camera = YAML.replace("camera_matrix:", "other_matrix:");
        let e = import("cam.yml", &no_camera, false, &ImportOptions::default()).unwrap_err();
        assert!(matches!(e, ImportError::Missing { .. }), "{e:?}");
        let nan = YAML.replace("6.5746697944293521e+002, 0.,", ".Nan, 0.,");
        let e = import("cam.yml", &nan, false, &ImportOptions::default()).unwrap_err();
        assert!(matches!(e, ImportError::Invalid { .. }), "{e:?}");
        let e = import(
            "cam.xml",
            "<opencv_storage><K>",
            true,
            &ImportOptions::default(),
        )
        .unwrap_err();
        assert!(matches!(e, ImportError::Unreadable { .. }), "{e:?}");
    }
}
