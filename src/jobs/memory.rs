//! The memory budget of the job service: parsing `--memory-budget` values
//! (`16GiB`, `512MiB`, plain bytes) and the default, a fraction of the
//! memory this process may use (physical memory from `/proc/meminfo`, or
//! the cgroup v2 limit `/sys/fs/cgroup/memory.max` when smaller).
//!
//! Admission itself is in [`super::service`] (refusal at submission) and
//! [`super::runner`] (a queued job starts only when its estimate fits
//! beside those running).

/// Share of the available memory the default budget allows.
pub const DEFAULT_BUDGET_FRACTION: f64 = 0.75;

/// Bytes of a size like `16GiB`, `512MiB`, `64M`, `2G`, `1.5GB` or `1048576`.
/// Binary suffixes (`KiB`, `MiB`, `GiB`, `TiB`, and the bare `K`, `M`, `G`,
/// `T`) are powers of 1024; `kB`, `MB`, `GB`, `TB` powers of 1000; `B` or
/// nothing is bytes. Case-insensitive, spaces allowed before the suffix.
///
/// # Errors
/// A message naming the value when it is not a positive size that fits in
/// 64 bits.
pub fn parse_byte_size(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let split = t.find(|c: char| !(c.is_ascii_digit() || c == '.')).unwrap_or(t.len());
    let (num, suffix) = t.split_at(split);
    let factor: f64 = match suffix.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 1.0,
        "k" | "kib" => 1024.0,
        "m" | "mib" => 1024f64.powi(2),
        "g" | "gib" => 1024f64.powi(3),
        "t" | "tib" => 1024f64.powi(4),
        "kb" => 1e3,
        "mb" => 1e6,
        "gb" => 1e9,
        "tb" => 1e12,
        other => return Err(format!("`{text}`: unknown unit `{other}` (use B, KiB, MiB, GiB, TiB, kB, MB, GB or TB)")),
    };
    let value: f64 = num.parse().map_err(|_| format!("`{text}` is not a size such as 16GiB, 512MiB or 1048576"))?;
    let bytes = value * factor;
    if !(bytes >= 1.0 && bytes < u64::MAX as f64) {
        return Err(format!("`{text}` must be at least 1 byte and below 16 EiB"));
    }
    Ok(bytes as u64)
}

/// `MemTotal` of `/proc/meminfo` in bytes.
fn physical_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// The cgroup v2 memory limit in bytes (`None` for `max` or no cgroup).
fn cgroup_limit() -> Option<u64> {
    std::fs::read_to_string("/sys/fs/cgroup/memory.max").ok()?.trim().parse().ok()
}

/// The default budget: [`DEFAULT_BUDGET_FRACTION`] of the smaller of
/// physical memory and the cgroup limit; unlimited when neither is known.
pub fn default_memory_budget() -> u64 {
    let available = match (physical_memory(), cgroup_limit()) {
        (Some(p), Some(c)) => p.min(c),
        (Some(p), None) => p,
        (None, Some(c)) => c,
        (None, None) => return u64::MAX,
    };
    (available as f64 * DEFAULT_BUDGET_FRACTION) as u64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_binary_and_decimal_units() {
        assert_eq!(parse_byte_size("16GiB"), Ok(16 << 30));
        assert_eq!(parse_byte_size("512MiB"), Ok(512 << 20));
        assert_eq!(parse_byte_size("64M"), Ok(64 << 20));
        assert_eq!(parse_byte_size("1.5 GB"), Ok(1_500_000_000));
        assert_eq!(parse_byte_size("1048576"), Ok(1 << 20));
        assert_eq!(parse_byte_size("2kib"), Ok(2048));
        for bad in ["", "0", "-5MiB", "12 parsecs", "1e300", "abc", "99999999999TiB"] {
            assert!(parse_byte_size(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn the_default_budget_is_a_fraction_of_memory() {
        let b = default_memory_budget();
        if let Some(p) = physical_memory() {
            assert!(b <= p && b > 0, "{b} of {p}");
        }
    }
}
