//! Command-line quantities: byte sizes (`512MiB`, `2GB`, `1G`) and durations (`10s`, `500ms`,
//! `2m`, `1.5h`, plain seconds).

/// Parses a byte size. Decimal units `kB`/`MB`/`GB`/`TB` are powers of 1000; binary units
/// `KiB`/`MiB`/`GiB`/`TiB` and the bare letters `K`/`M`/`G`/`T` are powers of 1024; no unit (or
/// `B`) means bytes. Case-insensitive; fractions allowed (`1.5GiB`).
pub fn parse_size_bytes(text: &str) -> Result<u64, String> {
    let trimmed = text.trim();
    let split = trimmed
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(trimmed.len());
    let (number, unit) = trimmed.split_at(split);
    let scale: f64 = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 1.0,
        "kb" => 1e3,
        "mb" => 1e6,
        "gb" => 1e9,
        "tb" => 1e12,
        "k" | "kib" => 1024.0,
        "m" | "mib" => 1024.0 * 1024.0,
        "g" | "gib" => 1024.0 * 1024.0 * 1024.0,
        "t" | "tib" => 1024.0 * 1024.0 * 1024.0 * 1024.0,
        other => {
            return Err(format!(
                "invalid size {text:?}: unknown unit {other:?} (use e.g. 512MiB, 2GB, 1G)"
            ));
        }
    };
    let value: f64 = number
        .parse()
        .map_err(|_| format!("invalid size {text:?}: use e.g. 512MiB, 2GB, 1G"))?;
    let bytes = value * scale;
    if !bytes.is_finite() || bytes < 0.0 || bytes > u64::MAX as f64 {
        return Err(format!("invalid size {text:?}: out of range"));
    }
    Ok(bytes.round() as u64)
}

pub use harvest_ipc::duration::parse_duration;

/// Formats a byte count for humans (`6.8 MB`), decimal units.
pub fn format_bytes(bytes: u64) -> String {
    const UNITS: [&str; 5] = ["B", "kB", "MB", "GB", "TB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1000.0 && unit + 1 < UNITS.len() {
        value /= 1000.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{bytes} B")
    } else {
        format!("{value:.1} {}", UNITS[unit])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn sizes_in_decimal_and_binary_units() {
        assert_eq!(parse_size_bytes("123"), Ok(123));
        assert_eq!(parse_size_bytes("2kB"), Ok(2000));
        assert_eq!(parse_size_bytes("1KiB"), Ok(1024));
        assert_eq!(parse_size_bytes("1.5GiB"), Ok(1_610_612_736));
        assert_eq!(parse_size_bytes("3 G"), Ok(3 * 1024 * 1024 * 1024));
        assert_eq!(parse_size_bytes("2MB"), Ok(2_000_000));
        assert!(parse_size_bytes("12 parsecs").is_err());
        assert!(parse_size_bytes("MB").is_err());
    }

    #[test]
    fn durations() {
        assert_eq!(parse_duration("250ms"), Ok(Duration::from_millis(250)));
        assert_eq!(parse_duration("1.5s"), Ok(Duration::from_millis(1500)));
        assert_eq!(parse_duration("2m"), Ok(Duration::from_secs(120)));
        assert_eq!(parse_duration("7"), Ok(Duration::from_secs(7)));
        assert!(parse_duration("-1s").is_err());
        assert!(parse_duration("soon").is_err());
    }

    #[test]
    fn human_bytes() {
        assert_eq!(format_bytes(999), "999 B");
        assert_eq!(format_bytes(6_800_000), "6.8 MB");
    }
}
