//! Sizes that overflow or cannot be allocated are typed errors, never a short buffer that
//! panics later or an allocation that aborts (issue #25).

use tagk_core::{
    ConfigError, EstimatorError, FrontEnd, FrontEndConfig, GreedyKaczmarz, KaczmarzConfig,
    OnlineEstimator, RandomizedKaczmarz, TagK, TailAveragedKaczmarz, UpdateInfo,
    checked_front_end_buffer_len, checked_kaczmarz_buffer_len, front_end_buffer_len,
    kaczmarz_buffer_len, zeroed_buffer,
};

/// `(n, m)` pairs whose buffer length overflows, or whose bytes no allocation can hold
/// (`1 << 58` scalars of 8 bytes is more than `isize::MAX`).
const HUGE: [(usize, usize); 5] = [
    (usize::MAX, usize::MAX),
    (1 << 40, 1 << 40),
    (usize::MAX, 1),
    (1, usize::MAX),
    (1 << 58, 8),
];

#[test]
fn overflowing_sizes_are_typed_errors() {
    let config = KaczmarzConfig::default();
    for (n, m) in HUGE {
        let too_large = Some(ConfigError::TooLarge { n, m });
        assert_eq!(TagK::<f64, Vec<f64>>::new(n, m, config).err(), too_large);
        assert_eq!(TagK::<f32, Vec<f32>>::new(n, m, config).err(), too_large);
        assert_eq!(
            GreedyKaczmarz::<f64, Vec<f64>>::new(n, m, config).err(),
            too_large
        );
        assert_eq!(
            RandomizedKaczmarz::<f64, Vec<f64>>::new(n, m, config).err(),
            too_large
        );
        assert_eq!(
            TailAveragedKaczmarz::<f64, Vec<f64>>::new(n, m, config).err(),
            too_large
        );
    }
    // The checked length says why; the const length saturates (never a short buffer).
    assert_eq!(checked_kaczmarz_buffer_len(usize::MAX, usize::MAX), None);
    assert_eq!(kaczmarz_buffer_len(usize::MAX, usize::MAX), usize::MAX);
    assert_eq!(checked_kaczmarz_buffer_len(1 << 40, 1 << 40), None);
    // In a borrowed buffer: the overflow is named, not a short buffer accepted.
    let mut buf = [0.0f64; 64];
    assert_eq!(
        TagK::with_storage(usize::MAX, usize::MAX, config, &mut buf[..]).err(),
        Some(ConfigError::TooLarge {
            n: usize::MAX,
            m: usize::MAX
        })
    );
    assert!(zeroed_buffer::<f64>(usize::MAX, 1, 1).is_err());
}

#[test]
fn normal_sizes_are_unchanged() {
    for (n, m) in [(1, 1), (10, 6), (120, 30), (10, 1000)] {
        assert_eq!(
            checked_kaczmarz_buffer_len(n, m),
            Some(kaczmarz_buffer_len(n, m))
        );
        let e = TagK::<f64, Vec<f64>>::new(n, m, KaczmarzConfig::default()).unwrap();
        assert_eq!(e.into_storage().len(), kaczmarz_buffer_len(n, m));
        assert_eq!(
            checked_front_end_buffer_len(n, m),
            Some(4 * n + m * (n + 1))
        );
        assert_eq!(front_end_buffer_len(n, m), 4 * n + m * (n + 1));
    }
    // Static sizing stays a constant expression.
    const LEN: usize = kaczmarz_buffer_len(10, 6);
    let _static_buffer = [0.0f32; LEN];
}

/// An estimator that only claims a size, to wrap in a [`FrontEnd`].
struct Claims(usize, usize);

impl OnlineEstimator<f64> for Claims {
    fn name(&self) -> &str {
        "claims"
    }
    fn dim(&self) -> usize {
        self.0
    }
    fn capacity(&self) -> usize {
        self.1
    }
    fn estimate(&self) -> &[f64] {
        &[]
    }
    fn update(&mut self, _: &[f64], _: &[f64]) -> Result<UpdateInfo, EstimatorError> {
        Err(EstimatorError::EmptyWindow)
    }
    fn reset(&mut self, _: &[f64]) -> Result<(), EstimatorError> {
        Ok(())
    }
}

#[test]
fn the_front_end_refuses_overflowing_sizes() {
    for (n, m) in HUGE {
        assert_eq!(
            FrontEnd::new(Claims(n, m), &[1.0], FrontEndConfig::default()).err(),
            Some(ConfigError::TooLarge { n, m }),
            "{n} × {m}"
        );
    }
    assert_eq!(checked_front_end_buffer_len(usize::MAX, 2), None);
    assert_eq!(front_end_buffer_len(usize::MAX, 2), usize::MAX);
}
