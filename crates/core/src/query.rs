//! Batch ray queries (`strahl trace`): rays from CSV, hits to CSV; and the points of point
//! queries (`strahl query`).
//!
//! Input header: `ox,oy,oz,dx,dy,dz` and optionally `tmin,tmax`, in any order. The direction
//! is normalised here, so `t` is the distance along the ray (the lecture's μ). Output header
//! [`HITS_HEADER`]: one row per ray in nearest mode (a miss has `object` = −1 and empty
//! fields), one row per intersection in `--all` mode, sorted by `t`.

use crate::math::{Ray, Real, V3};
use crate::primitives::Hit;
use std::fmt::Write as _;
use std::io::{BufRead, Read};
use std::path::Path;

pub const HITS_HEADER: &str = "ray,t,x,y,z,nx,ny,nz,object,prim,enter";
/// Largest rays file accepted: checked before it is read.
pub const MAX_RAYS_FILE_BYTES: u64 = 4 << 30;

/// One query ray, normalised, in f64 (each precision rounds it from here).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayQuery {
    pub origin: V3<f64>,
    pub dir: V3<f64>,
    pub tmin: f64,
    pub tmax: f64,
}

impl RayQuery {
    pub fn ray<R: Real>(&self) -> Ray<R> {
        Ray::new(self.origin.cast(), self.dir.cast())
    }
}

#[derive(Debug, thiserror::Error)]
#[error("{file}:{line}: {message}")]
pub struct RaysError {
    pub file: String,
    pub line: usize,
    pub message: String,
}

/// Longest line accepted in a rays file (eight numbers take at most about 200 bytes).
pub const MAX_RAYS_LINE_BYTES: usize = 4096;

/// Reads a rays CSV file: a regular file over [`MAX_RAYS_FILE_BYTES`] is refused before it
/// is read; any file is read a line at a time, so a stream without line breaks (/dev/zero)
/// fails at its first [`MAX_RAYS_LINE_BYTES`] bytes.
pub fn read_rays(path: &Path) -> anyhow::Result<Vec<RayQuery>> {
    let reader = open_query_file(path, "rays")?;
    Ok(parse_rays_from(reader, &path.display().to_string(), MAX_RAYS_FILE_BYTES)?)
}

/// Opens a query file (`what`: "rays" or "points") for reading a line at a time; a folder, or
/// a regular file over [`MAX_RAYS_FILE_BYTES`], is refused before anything is read.
fn open_query_file(path: &Path, what: &str) -> anyhow::Result<std::io::BufReader<std::fs::File>> {
    let cannot = |e: &dyn std::fmt::Display| anyhow::anyhow!("{}: cannot read {what} file: {e}", path.display());
    let file = std::fs::File::open(path).map_err(|e| cannot(&e))?;
    let meta = file.metadata().map_err(|e| cannot(&e))?;
    if meta.is_dir() {
        return Err(cannot(&"is a folder"));
    }
    if meta.is_file() && meta.len() > MAX_RAYS_FILE_BYTES {
        anyhow::bail!(
            "{}: {what} file is {} bytes; at most {MAX_RAYS_FILE_BYTES} are accepted",
            path.display(),
            meta.len()
        );
    }
    Ok(std::io::BufReader::new(file))
}

/// Parses rays CSV text; `file` names it in errors.
pub fn parse_rays(text: &str, file: &str) -> Result<Vec<RayQuery>, RaysError> {
    parse_rays_from(text.as_bytes(), file, u64::MAX)
}

/// The next line of `reader` (without its line break), or None at the end; `line` is its
/// number for errors. Lines are at most [`MAX_RAYS_LINE_BYTES`] long and hold no NUL byte.
fn next_line(reader: &mut impl BufRead, buf: &mut Vec<u8>, line: usize) -> Result<Option<String>, String> {
    buf.clear();
    let n = reader
        .by_ref()
        .take(MAX_RAYS_LINE_BYTES as u64 + 1)
        .read_until(b'\n', buf)
        .map_err(|e| format!("cannot read rays file: {e}"))?;
    if n == 0 {
        return Ok(None);
    }
    if buf.contains(&0) {
        return Err("not a text file (a NUL byte)".into());
    }
    if buf.last() == Some(&b'\n') {
        buf.pop();
    } else if buf.len() > MAX_RAYS_LINE_BYTES {
        return Err(format!("line longer than {MAX_RAYS_LINE_BYTES} bytes"));
    }
    let mut text = String::from_utf8(std::mem::take(buf)).map_err(|_| "not valid UTF-8".to_string())?;
    if line == 1 && text.starts_with('\u{feff}') {
        // A byte-order mark, as some spreadsheet programs write.
        text.drain(..'\u{feff}'.len_utf8());
    }
    Ok(Some(text))
}

/// A CSV file of numbers read a non-blank line at a time, at most `limit` bytes in all, with
/// the header's columns matched to the names a query file takes: what the rays and the points
/// files share.
struct NumberCsv<'a, B> {
    reader: B,
    file: &'a str,
    limit: u64,
    what: &'static str,
    buf: Vec<u8>,
    bytes: u64,
    line: usize,
}

impl<'a, B: BufRead> NumberCsv<'a, B> {
    fn new(reader: B, file: &'a str, limit: u64, what: &'static str) -> Self {
        Self { reader, file, limit, what, buf: Vec::new(), bytes: 0, line: 0 }
    }

    fn err(&self, line: usize, message: String) -> RaysError {
        RaysError { file: self.file.to_string(), line, message }
    }

    /// The next non-blank line, trimmed, with its number.
    fn next(&mut self) -> Result<Option<(usize, String)>, RaysError> {
        loop {
            self.line += 1;
            let ln = self.line;
            let Some(text) = next_line(&mut self.reader, &mut self.buf, ln).map_err(|m| self.err(ln, m))? else {
                return Ok(None);
            };
            self.bytes += text.len() as u64 + 1;
            if self.bytes > self.limit {
                let message = format!("the {} file is larger than {} bytes, the most accepted", self.what, self.limit);
                return Err(self.err(ln, message));
            }
            let t = text.trim();
            if !t.is_empty() {
                return Ok(Some((ln, t.to_string())));
            }
        }
    }

    /// Reads the header: for each of `known`, the column it is in (`usize::MAX` where it is
    /// absent; the first `required` must be present), and the number of columns. `expected`
    /// describes the header in errors.
    fn header(&mut self, known: &[&str], required: usize, expected: &str) -> Result<(Vec<usize>, usize), RaysError> {
        let (hline, header) =
            self.next()?.ok_or_else(|| self.err(1, format!("empty file: expected the header {expected}")))?;
        let names: Vec<&str> = header.split(',').map(str::trim).collect();
        let mut col = vec![usize::MAX; known.len()];
        for (i, name) in names.iter().enumerate() {
            let Some(k) = known.iter().position(|k| k == name) else {
                return Err(self.err(hline, format!("unknown column \"{name}\"; expected {expected}")));
            };
            if col[k] != usize::MAX {
                return Err(self.err(hline, format!("column \"{name}\" appears twice")));
            }
            col[k] = i;
        }
        if let Some(k) = (0..required).find(|&k| col[k] == usize::MAX) {
            return Err(self.err(hline, format!("missing column \"{}\"", known[k])));
        }
        Ok((col, names.len()))
    }

    /// The next data line's fields, checked against the header's count.
    fn fields(&mut self, columns: usize) -> Result<Option<(usize, Vec<String>)>, RaysError> {
        let Some((ln, line)) = self.next()? else { return Ok(None) };
        let fields: Vec<String> = line.split(',').map(|f| f.trim().to_string()).collect();
        if fields.len() != columns {
            return Err(self.err(ln, format!("{} fields, the header has {columns}", fields.len())));
        }
        Ok(Some((ln, fields)))
    }

    /// Field `s` of column `name` as a number.
    fn number(&self, ln: usize, name: &str, s: &str) -> Result<f64, RaysError> {
        s.parse().map_err(|_| self.err(ln, format!("{name}: not a number: \"{s}\"")))
    }
}

/// Parses rays CSV from `reader`, at most `limit` bytes; `file` names it in errors.
pub fn parse_rays_from(reader: impl BufRead, file: &str, limit: u64) -> Result<Vec<RayQuery>, RaysError> {
    const KNOWN: [&str; 8] = ["ox", "oy", "oz", "dx", "dy", "dz", "tmin", "tmax"];
    let mut csv = NumberCsv::new(reader, file, limit, "rays");
    let (col, columns) = csv.header(&KNOWN, 6, "ox,oy,oz,dx,dy,dz and optionally tmin,tmax")?;
    let mut rays = Vec::new();
    while let Some((ln, fields)) = csv.fields(columns)? {
        let mut v = [0.0f64; 8];
        v[6] = 0.0;
        v[7] = f64::INFINITY;
        for k in 0..8 {
            if col[k] == usize::MAX {
                continue;
            }
            let s = &fields[col[k]];
            let x = csv.number(ln, KNOWN[k], s)?;
            let finite_ok = x.is_finite() || (k == 7 && x == f64::INFINITY);
            if !finite_ok {
                return Err(csv.err(ln, format!("{}: must be finite, got {s}", KNOWN[k])));
            }
            v[k] = x;
        }
        let origin = V3::new(v[0], v[1], v[2]);
        let dir = unit_direction(V3::new(v[3], v[4], v[5]))
            .ok_or_else(|| csv.err(ln, "dx,dy,dz: the direction must be non-zero".into()))?;
        if !(v[6] >= 0.0) || !(v[7] > v[6]) {
            return Err(csv.err(ln, format!("tmin,tmax: need 0 <= tmin < tmax, got {} and {}", v[6], v[7])));
        }
        rays.push(RayQuery { origin, dir, tmin: v[6], tmax: v[7] });
    }
    Ok(rays)
}

/// `d` scaled to unit length, or None for the zero vector or one with an infinite component
/// (callers refuse NaN before).
#[inline]
pub fn unit_direction(d: V3<f64>) -> Option<V3<f64>> {
    unit_and_length(d).map(|(u, _)| u)
}

/// `d` scaled to unit length, and its length |d|; None as for [`unit_direction`]. The
/// components are first divided by the largest magnitude among them (exact for powers of two;
/// otherwise one rounding), so that the squared length neither overflows (1e308) nor underflows
/// (1e-300) before the square root. Each result carries at most seven roundings of ε = 2⁻⁵³
/// (the scaling, three in the sum of squares, the root, and the last division or product): each
/// component of the unit vector is within 7ε of d/|d|'s (the components are at most 1) and the
/// length within 7ε·|d|, about 1e-15, far below the f32 rounding the GPU's mirror applies next.
/// (Reciprocals and products instead of the six divisions measured no faster in the Python
/// package's `cast_rays`: the book's performance chapter.)
#[inline]
pub fn unit_and_length(d: V3<f64>) -> Option<(V3<f64>, f64)> {
    let m = d.abs().max_component();
    if !(m > 0.0) || !m.is_finite() {
        return None;
    }
    let s = d / m;
    let l = s.length();
    Some((s / l, l * m))
}

/// Appends the CSV rows for ray `index`: its hits, or one miss row when `hits` is empty and
/// `miss_row` is set (nearest mode).
pub fn write_hit_rows<R: Real>(out: &mut String, index: usize, ray: &Ray<R>, hits: &[Hit<R>], miss_row: bool) {
    if hits.is_empty() && miss_row {
        let _ = writeln!(out, "{index},,,,,,,,-1,,");
    }
    for h in hits {
        let p = ray.at(h.t);
        let n = h.normal;
        let _ = writeln!(
            out,
            "{index},{},{},{},{},{},{},{},{},{},{}",
            h.t, p.x, p.y, p.z, n.x, n.y, n.z, h.tag.object, h.tag.face, h.enter as u8
        );
    }
}

/// Header of `strahl query`'s output: one row per point (`distance` signed with `--signed`:
/// negative inside; an empty scene gives an empty `distance` and `object` −1).
pub const CLOSEST_HEADER: &str = "point,distance,x,y,z,nx,ny,nz,object,prim";

/// Reads a points CSV file (`strahl query --points`): header `x,y,z` in any order, finite
/// values; refused before it is read where it is larger than [`MAX_RAYS_FILE_BYTES`].
pub fn read_points(path: &Path) -> anyhow::Result<Vec<V3<f64>>> {
    let reader = open_query_file(path, "points")?;
    Ok(parse_points_from(reader, &path.display().to_string())?)
}

/// Parses points CSV text; `file` names it in errors.
pub fn parse_points(text: &str, file: &str) -> Result<Vec<V3<f64>>, RaysError> {
    parse_points_from(text.as_bytes(), file)
}

fn parse_points_from(reader: impl BufRead, file: &str) -> Result<Vec<V3<f64>>, RaysError> {
    const KNOWN: [&str; 3] = ["x", "y", "z"];
    let mut csv = NumberCsv::new(reader, file, MAX_RAYS_FILE_BYTES, "points");
    let (col, columns) = csv.header(&KNOWN, 3, "x,y,z")?;
    let mut points = Vec::new();
    while let Some((ln, fields)) = csv.fields(columns)? {
        let mut v = [0.0f64; 3];
        for k in 0..3 {
            let s = &fields[col[k]];
            let x = csv.number(ln, KNOWN[k], s)?;
            if !x.is_finite() {
                return Err(csv.err(ln, format!("{}: must be finite, got {s}", KNOWN[k])));
            }
            v[k] = x;
        }
        points.push(V3::new(v[0], v[1], v[2]));
    }
    Ok(points)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_files_parse_and_bad_ones_name_line_and_column() {
        let p = parse_points("z,x,y\n3,1,2\n\n-1,0,0.5\n", "p.csv").unwrap();
        assert_eq!(p, vec![V3::new(1.0, 2.0, 3.0), V3::new(0.0, 0.5, -1.0)]);
        let cases = [
            ("x,y\n", "p.csv:1: missing column \"z\""),
            ("x,y,z,w\n", "p.csv:1: unknown column \"w\""),
            ("x,y,x\n", "p.csv:1: column \"x\" appears twice"),
            ("x,y,z\n0,0,inf\n", "p.csv:2: z: must be finite"),
            ("x,y,z\n0,0,0\n0,a,0\n", "p.csv:3: y: not a number: \"a\""),
            ("x,y,z\n0,0\n", "p.csv:2: 2 fields, the header has 3"),
            ("", "p.csv:1: empty file"),
        ];
        for (text, want) in cases {
            let e = parse_points(text, "p.csv").unwrap_err().to_string();
            assert!(e.starts_with(want), "{e:?} does not start with {want:?}");
        }
    }

    #[test]
    fn parses_header_in_any_order_and_normalises() {
        let r = parse_rays("dz,dy,dx,oz,oy,ox,tmax\n10,0,0,1,2,3,5\n", "r.csv").unwrap();
        assert_eq!(r[0].origin, V3::new(3.0, 2.0, 1.0));
        assert_eq!(r[0].dir, V3::new(0.0, 0.0, 1.0));
        assert_eq!((r[0].tmin, r[0].tmax), (0.0, 5.0));
    }

    /// The unit vector and length agree with d / |d| (|d| computed apart, itself within 5ε
    /// where the squares stay in range) to the error bound unit_and_length states, over
    /// directions of every magnitude.
    #[test]
    fn unit_and_length_is_within_its_error_bound() {
        const EPS: f64 = f64::EPSILON / 2.0;
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        for i in 0..100_000 {
            let scale = 10f64.powi(i % 601 - 300);
            let d = V3::new(next(), next(), next()) * scale;
            let Some((u, length)) = unit_and_length(d) else { panic!("{d:?} refused") };
            // |d| without the scaling, where the squares stay in range.
            let exact_len = if (1e-100..1e100).contains(&scale) { d.length() } else { length };
            let reference = d / exact_len;
            assert!((u - reference).abs().max_component() <= 12.0 * EPS, "{d:?}: {u:?} vs {reference:?}");
            assert!((length - exact_len).abs() <= 12.0 * EPS * exact_len, "{d:?}: {length} vs {exact_len}");
            assert_eq!(unit_direction(d), Some(u));
        }
        assert_eq!(unit_and_length(V3::new(0.0, -0.0, 0.0)), None);
        assert_eq!(unit_and_length(V3::new(f64::INFINITY, 1.0, 0.0)), None);
    }

    /// Huge and tiny (finite, non-zero) directions are scaled before they are normalised: their
    /// squared length overflowed to infinity or underflowed to zero, and they were refused.
    #[test]
    fn extreme_directions_are_normalised() {
        let r =
            parse_rays("ox,oy,oz,dx,dy,dz\n0,0,0,1e308,1e308,1e308\n0,0,0,0,0,1e-300\n0,0,0,-5e-324,0,0\n", "r.csv")
                .unwrap();
        let third = 1.0 / 3f64.sqrt();
        assert!((r[0].dir - V3::splat(third)).abs().max_component() < 1e-15, "{:?}", r[0].dir);
        assert_eq!(r[1].dir, V3::new(0.0, 0.0, 1.0));
        assert_eq!(r[2].dir, V3::new(-1.0, 0.0, 0.0));
        assert!(parse_rays("ox,oy,oz,dx,dy,dz\n0,0,0,0,-0,0\n", "r.csv").is_err());
    }

    #[test]
    fn bad_rows_name_file_line_and_column() {
        let cases = [
            ("ox,oy,oz,dx,dy\n", "r.csv:1: missing column \"dz\""),
            ("ox,oy,oz,dx,dy,dz,w\n", "r.csv:1: unknown column \"w\""),
            ("ox,oy,oz,dx,dy,dz\n0,0,0,0,0,1\n0,0,0,0,0,0\n", "r.csv:3: dx,dy,dz: the direction must be non-zero"),
            ("ox,oy,oz,dx,dy,dz\n0,0,x,0,0,1\n", "r.csv:2: oz: not a number: \"x\""),
            ("ox,oy,oz,dx,dy,dz\n0,0,NaN,0,0,1\n", "r.csv:2: oz: must be finite"),
            ("ox,oy,oz,dx,dy,dz\n0,0,0,0,1\n", "r.csv:2: 5 fields, the header has 6"),
            ("ox,oy,oz,dx,dy,dz,tmin,tmax\n0,0,0,0,0,1,3,2\n", "r.csv:2: tmin,tmax: need 0 <= tmin < tmax"),
            ("", "r.csv:1: empty file"),
        ];
        for (text, want) in cases {
            let e = parse_rays(text, "r.csv").unwrap_err().to_string();
            assert!(e.starts_with(want), "{e:?} does not start with {want:?}");
        }
    }
}
