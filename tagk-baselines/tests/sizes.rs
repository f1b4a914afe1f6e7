//! Sizes that overflow or cannot be allocated are typed errors, never an abort or a panic
//! (issue #25).

use tagk_baselines::{ConfigError, KalmanConfig, KalmanFilter, Rls, RlsConfig};

#[test]
fn overflowing_or_unallocatable_sizes_are_typed_errors() {
    // Overflowing lengths, then a length that fits a `usize` but whose bytes do not fit an
    // allocation (2^61 scalars).
    for (n, m) in [
        (usize::MAX, usize::MAX),
        (1 << 40, 1 << 40),
        (usize::MAX, 1),
        (1, usize::MAX),
        (1 << 30, 1),
    ] {
        let too_large = Some(ConfigError::TooLarge { n, m });
        assert_eq!(Rls::new(n, m, RlsConfig::LOW).err(), too_large, "{n} × {m}");
        assert_eq!(Rls::rls_high(n, m).err(), too_large);
        assert_eq!(KalmanFilter::new(n, m, KalmanConfig::LOW).err(), too_large);
        assert_eq!(KalmanFilter::kf_high(n, m).err(), too_large);
    }
    // In a borrowed buffer: the overflow is named, not a short buffer.
    let mut buf = [0.0f64; 16];
    assert_eq!(
        Rls::<f64, _>::with_storage(usize::MAX, 2, RlsConfig::LOW, &mut buf[..]).err(),
        Some(ConfigError::TooLarge {
            n: usize::MAX,
            m: 2
        })
    );
    // Normal sizes still build.
    assert!(Rls::new(10, 6, RlsConfig::LOW).is_ok());
    assert!(KalmanFilter::new(10, 6, KalmanConfig::LOW).is_ok());
}
