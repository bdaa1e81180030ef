//! The FFT lengths the solver transforms at, which the orchestrator's scaling model counts too.

/// The smallest even length ≥ `at_least` with no prime factor above 7, where the FFT is fastest.
pub fn transform_length(at_least: usize) -> usize {
    (at_least.max(2)..)
        .find(|&p| {
            let mut rest = p;
            for factor in [2, 3, 5, 7] {
                while rest % factor == 0 {
                    rest /= factor;
                }
            }
            p % 2 == 0 && rest == 1
        })
        .expect("smooth numbers are unbounded")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_transform_length_is_the_next_even_7_smooth_number() {
        // 1056 = 2⁵·3·11; 1080 = 2³·3³·5. 257 is prime; 270 = 2·3³·5. 7 is odd.
        assert_eq!(transform_length(1056), 1080);
        assert_eq!(transform_length(257), 270);
        assert_eq!(transform_length(7), 8);
        assert_eq!(transform_length(1024), 1024);
        assert_eq!(transform_length(0), 2);
    }
}
