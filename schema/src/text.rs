//! Text as people read it, in the messages, tables, axes and summaries of both binaries: numbers
//! to four significant digits (`%.4g`), whole numbers in full; and text from elsewhere (a
//! solver's stderr, a study's strings) made safe for a terminal (`printable`).

/// The first `n` characters of `text` (all of it when shorter): a prefix cut at a character's
/// boundary, never inside one, as a byte slice of text from elsewhere could.
pub fn first_chars(text: &str, n: usize) -> &str {
    text.char_indices()
        .nth(n)
        .map_or(text, |(at, _)| &text[..at])
}

/// Significant digits of every number people read: tables, summaries, axes, messages.
pub const SIGNIFICANT: usize = 4;

/// A number as people read it: whole numbers in full (grid sizes, counts), others with
/// `SIGNIFICANT` digits, trailing zeros dropped, in scientific notation (`9.451e-9`) when fixed
/// notation would need more than four leading zeros or digits (as C's `%.4g`).
pub fn number(x: f64) -> String {
    if !x.is_finite() {
        return format!("{x}");
    }
    if x.fract() == 0.0 && x.abs() < 1e15 {
        return format!("{}", x as i64);
    }
    if scientific(x) {
        return scientific_text(x);
    }
    let exponent = decimal_exponent(x);
    let decimals = (SIGNIFICANT as i32 - 1 - exponent).max(0) as usize;
    trim_zeros(format!("{x:.decimals$}"))
}

/// A number as given, to its last digit (a refusal quotes what it refuses): its shortest form,
/// in scientific notation where the fixed one would be long (`1e-300`, not 300 characters).
pub fn exact(x: f64) -> String {
    let fixed = format!("{x}");
    match fixed.len() > 20 {
        true => format!("{x:e}"),
        false => fixed,
    }
}

/// Numbers that are read side by side (one axis's ticks, one column): in one notation, so
/// `1e-4` does not stand beside `0.01`; scientific for all when any needs it.
pub fn numbers_alike(values: &[f64]) -> Vec<String> {
    if values
        .iter()
        .any(|&x| x.is_finite() && x != 0.0 && scientific(x))
    {
        values
            .iter()
            .map(|&x| match x {
                0.0 => "0".to_string(),
                x if x.is_finite() => scientific_text(x),
                x => format!("{x}"),
            })
            .collect()
    } else {
        values.iter().map(|&x| number(x)).collect()
    }
}

/// The exponent of `x` once rounded to `SIGNIFICANT` digits (9.9996 rounds to 10: exponent 1).
fn decimal_exponent(x: f64) -> i32 {
    if x == 0.0 {
        return 0;
    }
    let rounded: f64 = format!("{:.*e}", SIGNIFICANT - 1, x).parse().unwrap_or(x);
    rounded.abs().log10().floor() as i32
}

fn scientific(x: f64) -> bool {
    let exponent = decimal_exponent(x);
    x.fract() != 0.0 && (exponent < -4 || exponent >= SIGNIFICANT as i32) || x.abs() >= 1e15
}

/// `9.451e-9`, `1e-4`, `-2.5e6`.
fn scientific_text(x: f64) -> String {
    let text = format!("{:.*e}", SIGNIFICANT - 1, x);
    let (mantissa, exponent) = text.split_once('e').unwrap_or((&text, "0"));
    format!("{}e{exponent}", trim_zeros(mantissa.to_string()))
}

fn trim_zeros(text: String) -> String {
    if !text.contains('.') {
        return text;
    }
    let trimmed = text.trim_end_matches('0').trim_end_matches('.');
    match trimmed {
        "-0" => "0".to_string(),
        t => t.to_string(),
    }
}

/// `text` with what a terminal would act on instead of showing escaped as `\u{…}`: control
/// characters but newline and tab (an escape sequence could move the cursor, clear the screen
/// or retitle the window), and the characters that reorder text (bidirectional overrides).
pub fn printable(text: &str) -> std::borrow::Cow<'_, str> {
    let acts = |c: char| {
        (c.is_control() && c != '\n' && c != '\t')
            || matches!(c, '\u{202a}'..='\u{202e}' | '\u{2066}'..='\u{2069}')
    };
    if !text.chars().any(acts) {
        return std::borrow::Cow::Borrowed(text);
    }
    let mut shown = String::with_capacity(text.len() + 8);
    for c in text.chars() {
        match acts(c) {
            true => shown.push_str(&format!("\\u{{{:x}}}", c as u32)),
            false => shown.push(c),
        }
    }
    std::borrow::Cow::Owned(shown)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_prefix_is_cut_between_characters() {
        assert_eq!(first_chars("0123456789", 8), "01234567");
        assert_eq!(first_chars("abc", 8), "abc");
        assert_eq!(first_chars("ééééééééé", 8), "éééééééé");
        assert_eq!(first_chars("a€€€€€€€€", 2), "a€");
        assert_eq!(first_chars("", 8), "");
    }

    #[test]
    fn an_exact_number_keeps_its_digits_and_is_never_long() {
        assert_eq!(exact(0.1), "0.1");
        assert_eq!(exact(1.00001), "1.00001");
        assert_eq!(exact(-1e-300), "-1e-300");
        assert_eq!(exact(1e300), "1e300");
        assert_eq!(exact(123456.5), "123456.5");
        assert_eq!(exact(f64::NAN), "NaN");
    }

    #[test]
    fn numbers_read_with_four_significant_digits() {
        let cases = [
            (0.000003, "3e-6"),
            (9.4513e-9, "9.451e-9"),
            (4e-7, "4e-7"),
            (0.03125, "0.03125"),
            (2.0700001, "2.07"),
            (-0.18, "-0.18"),
            (1024.0, "1024"),
            (16384.0, "16384"),
            (0.0, "0"),
            (1.0, "1"),
            (123.456, "123.5"),
            (12345.6, "1.235e4"),
            (9.99996, "10"),
            (0.00012346, "0.0001235"),
            (-0.0, "0"),
            (2e20, "2e20"),
        ];
        for (x, text) in cases {
            assert_eq!(number(x), text, "{x}");
        }
        assert_eq!(numbers_alike(&[1e-5, 0.01, 1.0]), ["1e-5", "1e-2", "1e0"]);
        assert_eq!(numbers_alike(&[1e-4, 0.01, 1.0]), ["0.0001", "0.01", "1"]);
        assert_eq!(numbers_alike(&[0.0, 0.5, 1.0]), ["0", "0.5", "1"]);
    }

    #[test]
    fn what_a_terminal_acts_on_is_shown_escaped() {
        assert_eq!(printable("plain\ttext\n"), "plain\ttext\n");
        assert_eq!(printable("\u{1b}[2Jcleared"), "\\u{1b}[2Jcleared");
        assert_eq!(
            printable("a\u{202e}b\rc\u{7f}"),
            "a\\u{202e}b\\u{d}c\\u{7f}"
        );
    }
}
