//! Cycle counters: how the harness times one update.
//!
//! - `DwtCycleCounter` (feature `cortex-m`, `target_arch = "arm"`, ARMv7-M or later): the
//!   Cortex-M Data Watchpoint and Trace unit's `CYCCNT`, one tick per core clock cycle.
//!   QEMU does not model it (it reads 0 there); use the instruction-counting plugin instead.
//! - [`StdClock`] (feature `std`): nanoseconds from `std::time::Instant` on the host.
//! - [`NullCounter`]: always 0, for runs where only the results matter.

/// A free-running 32-bit counter read around each update.
pub trait CycleCounter {
    /// Reads the counter. It wraps at 2³²; use [`elapsed`](Self::elapsed) for intervals.
    fn now(&mut self) -> u32;

    /// Ticks per second (the core clock for `CYCCNT`, 10⁹ for [`StdClock`]), or 0 if the
    /// counter does not run.
    fn ticks_per_second(&self) -> u64;

    /// Ticks from `start` to `end`, correct across one wrap (intervals shorter than 2³² ticks).
    fn elapsed(&self, start: u32, end: u32) -> u32 {
        end.wrapping_sub(start)
    }
}

impl<C: CycleCounter + ?Sized> CycleCounter for &mut C {
    fn now(&mut self) -> u32 {
        (**self).now()
    }
    fn ticks_per_second(&self) -> u64 {
        (**self).ticks_per_second()
    }
}

/// A counter that never runs: every read is 0.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct NullCounter;

impl CycleCounter for NullCounter {
    fn now(&mut self) -> u32 {
        0
    }
    fn ticks_per_second(&self) -> u64 {
        0
    }
}

/// The DWT cycle counter (`CYCCNT`) of an ARMv7-M or later core, in core clock cycles.
#[cfg(all(feature = "cortex-m", target_arch = "arm"))]
#[derive(Debug)]
pub struct DwtCycleCounter {
    core_hz: u32,
}

#[cfg(all(feature = "cortex-m", target_arch = "arm"))]
impl DwtCycleCounter {
    /// Enables trace in the DCB, unlocks the DWT (needed on some Cortex-M7 parts), and starts
    /// `CYCCNT`. `core_hz` is the core clock in Hz (600 MHz on a Teensy 4.1).
    pub fn new(
        dcb: &mut cortex_m::peripheral::DCB,
        dwt: &mut cortex_m::peripheral::DWT,
        core_hz: u32,
    ) -> Self {
        dcb.enable_trace();
        cortex_m::peripheral::DWT::unlock();
        dwt.enable_cycle_counter();
        Self { core_hz }
    }
}

#[cfg(all(feature = "cortex-m", target_arch = "arm"))]
impl CycleCounter for DwtCycleCounter {
    #[inline]
    fn now(&mut self) -> u32 {
        cortex_m::peripheral::DWT::cycle_count()
    }
    fn ticks_per_second(&self) -> u64 {
        u64::from(self.core_hz)
    }
}

/// Nanoseconds since construction from the host's monotonic clock, truncated to 32 bits.
#[cfg(feature = "std")]
#[derive(Debug, Clone, Copy)]
pub struct StdClock {
    origin: std::time::Instant,
}

#[cfg(feature = "std")]
impl StdClock {
    /// Starts the clock.
    pub fn new() -> Self {
        Self {
            origin: std::time::Instant::now(),
        }
    }
}

#[cfg(feature = "std")]
impl Default for StdClock {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(feature = "std")]
impl CycleCounter for StdClock {
    fn now(&mut self) -> u32 {
        // Truncation is the point: the counter wraps like CYCCNT.
        self.origin.elapsed().as_nanos() as u32
    }
    fn ticks_per_second(&self) -> u64 {
        1_000_000_000
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn elapsed_is_correct_across_a_wrap() {
        let c = NullCounter;
        assert_eq!(c.elapsed(u32::MAX - 4, 10), 15);
        assert_eq!(c.elapsed(100, 250), 150);
    }

    #[cfg(feature = "std")]
    #[test]
    fn std_clock_advances_over_a_sleep() {
        let mut c = StdClock::new();
        let t0 = c.now();
        std::thread::sleep(std::time::Duration::from_millis(2));
        let t1 = c.now();
        assert!(c.elapsed(t0, t1) >= 2_000_000);
        assert_eq!(c.ticks_per_second(), 1_000_000_000);
    }
}
