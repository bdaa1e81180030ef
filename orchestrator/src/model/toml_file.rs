//! TOML study files and site profiles, read as the JSON ones are (`schema::json::Strict`): a
//! number that is not finite (`nan`, `inf`) and a date or time are refused naming their place,
//! where a plain `toml::from_str::<Value>` would turn the first into `null` ("not given") and
//! the second into a map no field expects.

use serde_json::Value;

/// `text` as one value; an error names the place at fault (`sweep[0].product.dt[1]: …`).
pub fn parse(text: &str) -> Result<Value, String> {
    let deserializer =
        toml::de::Deserializer::parse(text).map_err(|e| e.message().trim().to_string())?;
    serde_path_to_error::deserialize::<_, schema::json::Strict>(deserializer)
        .map(|strict| strict.0)
        .map_err(|e| {
            let message = e.inner().message().trim().to_string();
            match e.path().to_string().as_str() {
                "." => message,
                place => format!("`{place}`: {message}"),
            }
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_that_are_not_finite_and_dates_are_refused_naming_their_place() {
        let value = parse("a = 1.5\nb = [1, \"x\"]\n[c]\nd = true").unwrap();
        assert_eq!(
            value,
            serde_json::json!({"a": 1.5, "b": [1, "x"], "c": {"d": true}})
        );
        for (text, place) in [
            ("dt = nan", "`dt`"),
            ("[base]\nt_end = inf", "`base.t_end`"),
            ("x = [1.0, -inf]", "`x[1]`"),
        ] {
            let error = parse(text).unwrap_err();
            assert!(
                error.contains(place) && error.contains("not a finite number"),
                "{text}: {error}"
            );
        }
        let error = parse("[resources]\ntime = 01:00:00").unwrap_err();
        assert!(
            error.contains("`resources.time`") && error.contains("quote it"),
            "{error}"
        );
        let error = parse("a = 1\na = 2").unwrap_err();
        assert!(
            error.contains("duplicate") || error.contains("twice"),
            "{error}"
        );
    }
}
