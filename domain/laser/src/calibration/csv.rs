//! Calibration samples as CSV: one sample per line, `u_bar,v_bar,z_m` (normalised coordinates,
//! depth in metres). Blank lines and lines starting with `#` are skipped; a first line naming
//! the columns (`u_bar,v_bar,z_m`) is allowed. Errors name the file and the 1-based line.

use std::io::Write;
use std::path::{Path, PathBuf};

use super::sample::CalibrationSample;

/// Why a sample file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum SampleFileError {
    /// The file could not be opened, read or written.
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A line does not have exactly three comma-separated fields.
    #[error("{path}:{line}: expected 3 fields u_bar,v_bar,z_m, found {found}")]
    FieldCount {
        path: PathBuf,
        line: usize,
        found: usize,
    },
    /// A field is not a number.
    #[error("{path}:{line}: {field} = {value:?} is not a number")]
    NotANumber {
        path: PathBuf,
        line: usize,
        field: &'static str,
        value: String,
    },
    /// A field is NaN or infinite.
    #[error("{path}:{line}: {field} = {value} is not finite")]
    NotFinite {
        path: PathBuf,
        line: usize,
        field: &'static str,
        value: f64,
    },
    /// The file holds no sample.
    #[error("{path}: no samples")]
    Empty { path: PathBuf },
}

const FIELDS: [&str; 3] = ["u_bar", "v_bar", "z_m"];

/// Reads a sample file.
pub fn read_samples_csv(path: &Path) -> Result<Vec<CalibrationSample>, SampleFileError> {
    let text = std::fs::read_to_string(path).map_err(|source| SampleFileError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_samples_csv(&text, path)
}

/// Parses sample-file text; `path` only names the source in errors.
pub fn parse_samples_csv(
    text: &str,
    path: &Path,
) -> Result<Vec<CalibrationSample>, SampleFileError> {
    let mut samples = Vec::new();
    let mut first_content_line = true;
    for (line_index, line) in text.lines().enumerate() {
        let line_number = line_index + 1;
        let content = line.trim();
        if content.is_empty() || content.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = content.split(',').map(str::trim).collect();
        if std::mem::take(&mut first_content_line) && fields == FIELDS {
            continue;
        }
        if fields.len() != FIELDS.len() {
            return Err(SampleFileError::FieldCount {
                path: path.to_path_buf(),
                line: line_number,
                found: fields.len(),
            });
        }
        let mut values = [0.0_f64; 3];
        for ((value, field), name) in values.iter_mut().zip(&fields).zip(FIELDS) {
            *value = field.parse().map_err(|_| SampleFileError::NotANumber {
                path: path.to_path_buf(),
                line: line_number,
                field: name,
                value: (*field).to_string(),
            })?;
            if !value.is_finite() {
                return Err(SampleFileError::NotFinite {
                    path: path.to_path_buf(),
                    line: line_number,
                    field: name,
                    value: *value,
                });
            }
        }
        samples.push(CalibrationSample {
            u_bar: values[0],
            v_bar: values[1],
            z_m: values[2],
        });
    }
    if samples.is_empty() {
        return Err(SampleFileError::Empty {
            path: path.to_path_buf(),
        });
    }
    Ok(samples)
}

/// Writes samples with a header line, full `f64` precision (reads back bit-exact).
pub fn write_samples_csv(
    path: &Path,
    samples: &[CalibrationSample],
) -> Result<(), SampleFileError> {
    let io_error = |source| SampleFileError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut file = std::io::BufWriter::new(std::fs::File::create(path).map_err(io_error)?);
    writeln!(file, "{}", FIELDS.join(",")).map_err(io_error)?;
    for sample in samples {
        writeln!(
            file,
            "{:?},{:?},{:?}",
            sample.u_bar, sample.v_bar, sample.z_m
        )
        .map_err(io_error)?;
    }
    file.flush().map_err(io_error)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_header_comments_and_values() {
        let text = "u_bar,v_bar,z_m\n# board 1\n-0.1, 0.2, 0.75\n\n0.05,-0.3,1.1\n";
        let samples = parse_samples_csv(text, Path::new("s.csv")).expect("parse");
        assert_eq!(
            samples,
            vec![
                CalibrationSample {
                    u_bar: -0.1,
                    v_bar: 0.2,
                    z_m: 0.75
                },
                CalibrationSample {
                    u_bar: 0.05,
                    v_bar: -0.3,
                    z_m: 1.1
                },
            ]
        );
    }

    #[test]
    fn errors_name_file_line_and_field() {
        let path = Path::new("board.csv");
        let error = parse_samples_csv("0.1,0.2,0.7\n0.1,abc,0.8\n", path).expect_err("bad");
        assert_eq!(
            error.to_string(),
            "board.csv:2: v_bar = \"abc\" is not a number"
        );
        let error = parse_samples_csv("0.1,0.2\n", path).expect_err("short");
        assert_eq!(
            error.to_string(),
            "board.csv:1: expected 3 fields u_bar,v_bar,z_m, found 2"
        );
        let error = parse_samples_csv("# x\n0.1,0.2,NaN\n", path).expect_err("nan");
        assert_eq!(error.to_string(), "board.csv:2: z_m = NaN is not finite");
        assert!(matches!(
            parse_samples_csv("# only\n", path),
            Err(SampleFileError::Empty { .. })
        ));
        let missing = read_samples_csv(Path::new("/nonexistent/samples.csv")).expect_err("missing");
        assert!(
            missing
                .to_string()
                .starts_with("/nonexistent/samples.csv: ")
        );
    }

    #[test]
    fn write_then_read_is_exact() {
        let dir = std::env::temp_dir().join(format!("harvest-laser-csv-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let path = dir.join("samples.csv");
        let samples = vec![
            CalibrationSample {
                u_bar: -0.123456789012345,
                v_bar: 1e-17,
                z_m: 0.6000000000000001,
            },
            CalibrationSample {
                u_bar: 0.3,
                v_bar: -0.25,
                z_m: 1.2,
            },
        ];
        write_samples_csv(&path, &samples).expect("write");
        assert_eq!(read_samples_csv(&path).expect("read"), samples);
        std::fs::remove_dir_all(&dir).expect("cleanup");
    }
}
