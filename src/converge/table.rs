//! `strahl converge`'s text outputs: the CSV file and the Markdown table of its rows.

use super::Row;
use anyhow::Result;
use std::fmt::Write as _;
use std::path::Path;

/// Writes `rows` as CSV: `backend,label,spp,seconds,rmse,rmse_clamped,rel_mse,mean_flip`,
/// atomically (a run rewrites it after every row, so an interrupted run keeps what it measured).
pub fn write_csv(rows: &[Row], path: &Path) -> Result<()> {
    let mut s = String::from("backend,label,spp,seconds,rmse,rmse_clamped,rel_mse,mean_flip\n");
    for r in rows {
        let e = &r.errors;
        writeln!(
            s,
            "{},{},{},{},{},{},{},{}",
            csv_field(&r.backend),
            csv_field(&r.label),
            r.spp,
            r.seconds,
            e.rmse,
            e.rmse_clamped,
            e.rel_mse,
            e.mean_flip
        )
        .expect("writing to a String");
    }
    strahl_core::output::write_bytes_atomic(path, s.as_bytes())
}

/// A CSV field, quoted (RFC 4180) when it holds a comma, a quote or a line break.
fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) { format!("\"{}\"", s.replace('"', "\"\"")) } else { s.to_string() }
}

/// A Markdown table of `rows`, one line each.
pub fn table(rows: &[Row]) -> String {
    let mut s = String::from(
        "| backend | spp | seconds | samples/s (M) | RMSE | RMSE clamped | relMSE | mean FLIP |\n\
         |---|--:|--:|--:|--:|--:|--:|--:|\n",
    );
    for r in rows {
        let rate = r.samples_per_second();
        let rate = if rate.is_finite() { format!("{:.2}", rate / 1e6) } else { "-".to_string() };
        let e = &r.errors;
        writeln!(
            s,
            "| {} | {} | {:.3} | {} | {} | {} | {} | {} |",
            r.label.replace('|', "\\|"),
            r.spp,
            r.seconds,
            rate,
            sig4(e.rmse),
            sig4(e.rmse_clamped),
            sig4(e.rel_mse),
            sig4(e.mean_flip)
        )
        .expect("writing to a String");
    }
    s
}

/// `x` to 4 significant digits, in scientific notation when it is very small or large.
fn sig4(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let mag = x.abs().log10().floor() as i32;
    if (-3..=4).contains(&mag) { format!("{:.*}", (3 - mag).max(0) as usize, x) } else { format!("{x:.3e}") }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use strahl_metrics::Errors;

    pub(crate) fn sample_rows() -> Vec<Row> {
        let e = |rmse: f64| Errors { rmse, rmse_clamped: rmse / 2.0, rel_mse: rmse * 2.0, mean_flip: rmse / 4.0 };
        let row = |backend: &str, label: &str, spp: u32, seconds: f64, rmse: f64| Row {
            backend: backend.to_string(),
            label: label.to_string(),
            width: 640,
            height: 480,
            spp,
            seconds,
            errors: e(rmse),
        };
        vec![
            row("gpu", "gpu (llvmpipe (LLVM 15.0.6, 256 bits))", 1, 0.02, 0.1),
            row("gpu", "gpu (llvmpipe (LLVM 15.0.6, 256 bits))", 2, 0.04, 0.071),
            row("gpu", "gpu (llvmpipe (LLVM 15.0.6, 256 bits))", 4, 0.08, 0.05),
            row("cpu", "cpu (2 threads)", 1, 0.3, 0.1),
            row("cpu", "cpu (2 threads)", 2, 0.6, 0.071),
            row("cpu", "cpu (2 threads)", 4, 1.2, 0.05),
        ]
    }

    #[test]
    fn csv_has_the_header_and_one_quoted_line_per_row() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.csv");
        let mut rows = sample_rows();
        rows[5].label = "say \"hi\"".to_string();
        write_csv(&rows, &path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "backend,label,spp,seconds,rmse,rmse_clamped,rel_mse,mean_flip");
        assert_eq!(lines.len(), rows.len() + 1);
        assert_eq!(lines[1], "gpu,\"gpu (llvmpipe (LLVM 15.0.6, 256 bits))\",1,0.02,0.1,0.05,0.2,0.025");
        assert!(lines[4].starts_with("cpu,cpu (2 threads),1,0.3,"));
        assert!(lines[6].starts_with("cpu,\"say \"\"hi\"\"\",4,1.2,"));
    }

    #[test]
    fn table_has_one_line_per_row() {
        let mut rows = sample_rows();
        rows[0].seconds = 0.0;
        let t = table(&rows);
        let lines: Vec<&str> = t.lines().collect();
        assert_eq!(lines.len(), rows.len() + 2);
        assert!(lines[0].starts_with("| backend | spp | seconds | samples/s (M) |"));
        assert_eq!(lines[1].matches('|').count(), lines[0].matches('|').count());
        assert_eq!(
            lines[2],
            "| gpu (llvmpipe (LLVM 15.0.6, 256 bits)) | 1 | 0.000 | - | 0.1000 | 0.05000 | 0.2000 | 0.02500 |"
        );
        // 640 × 480 × 4 samples in 1.2 s.
        assert!(lines[7].contains("| 1.02 |"), "{}", lines[7]);
        assert_eq!(sig4(12345.6), "12346");
        assert_eq!(sig4(123456.0), "1.235e5");
        assert_eq!(sig4(0.000_012_34), "1.234e-5");
        assert_eq!(sig4(1.5), "1.500");
    }
}
