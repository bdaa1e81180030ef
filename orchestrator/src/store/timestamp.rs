//! A record's `provenance.timestamp`, read as the time it says or not at all: an RFC 3339 UTC
//! time `YYYY-MM-DDTHH:MM:SS[.f]Z` with every field in its range. A record's text is not trusted
//! (a `NaN` second, month 13 or a year of seventeen digits would order records or place them on
//! an axis wrongly): what does not read is unknown.

use schema::record::Stored;

/// Seconds since 1970 of `stamp`, or `None` when it is not a time.
pub fn seconds(stamp: &str) -> Option<f64> {
    let (date, time) = stamp.strip_suffix('Z')?.split_once('T')?;
    let whole = |text: &str, digits: usize| -> Option<i64> {
        (text.len() == digits && text.bytes().all(|b| b.is_ascii_digit()))
            .then(|| text.parse().ok())?
    };
    let mut date = date.split('-');
    let (y, m, d) = (
        whole(date.next()?, 4)?,
        whole(date.next()?, 2)?,
        whole(date.next()?, 2)?,
    );
    let mut clock = time.split(':');
    let (h, min, s) = (
        whole(clock.next()?, 2)?,
        whole(clock.next()?, 2)?,
        clock.next()?,
    );
    if date.next().is_some() || clock.next().is_some() {
        return None;
    }
    let second_digits = s.split_once('.').map_or(s, |(whole, _)| whole);
    let fraction_ok = s
        .split_once('.')
        .is_none_or(|(_, f)| !f.is_empty() && f.bytes().all(|b| b.is_ascii_digit()));
    let digits = second_digits.len() == 2 && second_digits.bytes().all(|b| b.is_ascii_digit());
    let s: f64 = (digits && fraction_ok).then(|| s.parse().ok()).flatten()?;
    let days_in_month = match m {
        2 if y % 4 == 0 && (y % 100 != 0 || y % 400 == 0) => 29,
        2 => 28,
        4 | 6 | 9 | 11 => 30,
        _ => 31,
    };
    let in_range = (1970..=9999).contains(&y)
        && (1..=12).contains(&m)
        && (1..=days_in_month).contains(&d)
        && h < 24
        && min < 60
        && s < 61.0;
    if !in_range {
        return None;
    }
    // Days from civil (Howard Hinnant's algorithm).
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let year_of_era = y - era * 400;
    let day_of_year = (153 * (if m > 2 { m - 3 } else { m + 9 }) + 2) / 5 + d - 1;
    let day_of_era = year_of_era * 365 + year_of_era / 4 - year_of_era / 100 + day_of_year;
    let days = era * 146_097 + day_of_era - 719_468;
    Some(days as f64 * 86_400.0 + (h * 3600 + min * 60) as f64 + s)
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
        for bad in [
            "2026-01-01T00:00:NaNZ",
            "2026-01-01T00:00:infZ",
            "2026-13-01T00:00:00Z",
            "2026-02-29T00:00:00Z",
            "2026-01-01T24:00:00Z",
            "99999999999999999-01-01T00:00:00Z",
            "1969-12-31T23:59:59Z",
            "2026-01-01T00:00:00",
            "2026-01-01T00:00:00.Z",
            "2026-01-01T00:00:+1Z",
            "",
        ] {
            assert_eq!(seconds(bad), None, "{bad}");
        }
    }
}
