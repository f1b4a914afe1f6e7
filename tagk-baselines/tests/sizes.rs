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

/// The buffer-length `const fn`s saturate where the length overflows (a `usize::MAX` buffer is
/// refused by every constructor), and their checked twins say `None`; an exact length is the
/// closed form, computed here in `u128`.
#[test]
fn buffer_lengths_saturate_and_their_checked_twins_say_none() {
    use tagk_baselines::{
        checked_compact_covariance_buffer_len, checked_covariance_buffer_len,
        compact_covariance_buffer_len, covariance_buffer_len,
    };
    // In checked u128 (each operand < 2⁶⁴); `None` past it.
    let exact = |n: u128, m: u128, f: u128| {
        (n * n)
            .checked_mul(1 + f)?
            .checked_add((3 + f) * n)?
            .checked_add((2 * m).checked_mul(n)?)?
            .checked_add(m * m)?
            .checked_add(3 * m)
    };
    for (n, m) in [
        (usize::MAX, usize::MAX),
        (1 << 32, 1),
        (1, 1 << 32),
        (usize::MAX, 0),
        (3_037_000_499, 0),
        (120, 30),
        (0, 0),
    ] {
        for (f, checked, saturating) in [
            (
                1,
                checked_covariance_buffer_len as fn(usize, usize) -> Option<usize>,
                covariance_buffer_len as fn(usize, usize) -> usize,
            ),
            (
                0,
                checked_compact_covariance_buffer_len,
                compact_covariance_buffer_len,
            ),
        ] {
            let want = exact(n as u128, m as u128, f).and_then(|x| usize::try_from(x).ok());
            assert_eq!(checked(n, m), want, "{n} × {m}, fallback {f}");
            assert_eq!(saturating(n, m), want.unwrap_or(usize::MAX));
        }
    }
    // Still a `const fn` that sizes a static array.
    const LEN: usize = compact_covariance_buffer_len(120, 30);
    static BUF: [f32; LEN] = [0.0; LEN];
    assert_eq!(BUF.len(), 22_950);
}
