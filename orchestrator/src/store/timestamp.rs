//! A record's `provenance.timestamp`, read as the time it says or not at all: an RFC 3339 UTC
//! time `YYYY-MM-DDTHH:MM:SS[.f]Z` with every field in its range (as `humantime` reads it). A record's text is not trusted
//! (a `NaN` second, month 13 or a year of seventeen digits would order records or place them on
//! an axis wrongly): what does not read is unknown.

use schema::record::Stored;

/// Seconds since 1970 of `stamp`, or `None` when it is not a time. `humantime` (which the
/// solver writes it with) reads the RFC 3339 form strictly: fixed widths, fields in range, years
/// 1970 to 9999.
pub fn seconds(stamp: &str) -> Option<f64> {
    let time = humantime::parse_rfc3339(stamp).ok()?;
    let since = time.duration_since(std::time::UNIX_EPOCH).ok()?;
    Some(since.as_secs_f64())
}

/// The time `record` was made, when its provenance says one that reads.
pub fn record_time(record: &Stored) -> Option<f64> {
    seconds(&record.provenance()?.timestamp)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_read_only_when_every_field_is_in_range() {
        assert_eq!(seconds("1970-01-02T12:00:00Z"), Some(1.5 * 86_400.0));
        assert_eq!(seconds("2000-03-01T00:00:00Z"), Some(11_017.0 * 86_400.0));
        assert_eq!(
            seconds("2024-02-29T00:00:00.25Z"),
            Some(19_782.0 * 86_400.0 + 0.25)
        );
        // An empty fraction is the whole second (humantime reads it so).
        assert_eq!(seconds("1970-01-01T00:00:01.Z"), Some(1.0));
        for bad in [
            "2026-01-01T00:00:NaNZ",
            "2026-01-01T00:00:infZ",
            "2026-13-01T00:00:00Z",
            "2026-02-29T00:00:00Z",
            "2026-01-01T24:00:00Z",
            "99999999999999999-01-01T00:00:00Z",
            "1969-12-31T23:59:59Z",
            "2026-01-01T00:00:00",
            "2026-01-01T00:00:+1Z",
            "",
        ] {
            assert_eq!(seconds(bad), None, "{bad}");
        }
    }
}
