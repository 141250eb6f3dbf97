//! The 170 MHz clock tree of the STM32G474 on a NUCLEO-G474RE.
//!
//! ```text
//! HSE 24 MHz crystal (Nucleo X3)
//!   -> PLLM /6      =   4 MHz  PLL input (must be 2.66..16 MHz)
//!   -> PLLN x85     = 340 MHz  VCO (must be 96..344 MHz)
//!   -> PLLR /2      = 170 MHz  SYSCLK = HCLK (AHB /1): the G4's maximum, boost mode on
//!      APB1 /1      = 170 MHz  PCLK1; TIM2/TIM3 kernel clock = 170 MHz (x1: APB prescaler 1)
//!      APB2 /1      = 170 MHz  PCLK2; TIM1/TIM15 kernel clock = 170 MHz
//! HSI48 (RC) trimmed by CRS from USB start-of-frame -> USB 48 MHz
//! ```
//!
//! The crystal, not the 1 %-class HSI, clocks the trigger timer: every edge
//! of a scan is a tick count of this clock, so its ppm error is the scan's
//! timing error. USB takes HSI48 + CRS so the PLL stays free for 170 MHz.

use embassy_stm32::rcc::{
    mux, AHBPrescaler, APBPrescaler, Hse, HseMode, Hsi48Config, Pll, PllMul, PllPreDiv, PllRDiv,
    PllSource, Sysclk,
};
use embassy_stm32::time::Hertz;
use embassy_stm32::Config;

/// Frequency of the NUCLEO-G474RE's HSE crystal (X3).
pub const HSE_HZ: u32 = 24_000_000;
/// Timer kernel clock of TIM2 (and TIM3): one edge tick.
pub const TIMER_CLOCK_HZ: u32 = 170_000_000;

/// The embassy configuration for the tree drawn above.
pub fn config() -> Config {
    let mut config = Config::default();
    let rcc = &mut config.rcc;
    rcc.hse = Some(Hse {
        freq: Hertz(HSE_HZ),
        mode: HseMode::Oscillator,
    });
    rcc.pll = Some(Pll {
        source: PllSource::HSE,
        prediv: PllPreDiv::DIV6, // 24 MHz / 6 = 4 MHz
        mul: PllMul::MUL85,      // 4 MHz x 85 = 340 MHz VCO
        divp: None,
        divq: None,
        divr: Some(PllRDiv::DIV2), // 340 MHz / 2 = 170 MHz SYSCLK
    });
    rcc.sys = Sysclk::PLL1_R;
    rcc.ahb_pre = AHBPrescaler::DIV1; // HCLK 170 MHz
    rcc.apb1_pre = APBPrescaler::DIV1; // PCLK1 170 MHz, TIM2/3 at 170 MHz
    rcc.apb2_pre = APBPrescaler::DIV1; // PCLK2 170 MHz
    rcc.boost = true; // range-1 boost: required above 150 MHz
    rcc.hsi48 = Some(Hsi48Config {
        sync_from_usb: true, // CRS trims HSI48 to the host's 1 kHz SOF
    });
    rcc.mux.clk48sel = mux::Clk48sel::HSI48;
    config
}

// The tree above and the limits the host validates plans against must agree:
// every edge tick the host computes is a tick of this clock.
const _: () = assert!(TIMER_CLOCK_HZ == protocol::BoardLimits::STM32G474.timer_clock_hz);
const _: () = assert!(HSE_HZ / 6 * 85 / 2 == TIMER_CLOCK_HZ);
