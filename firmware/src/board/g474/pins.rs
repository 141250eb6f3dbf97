//! The NUCLEO-G474RE pin map: every pin, timer and DMA channel the firmware
//! uses is named once, here (README.md "Pin map" is the wiring view of it).
//!
//! | line                    | board-core channel | peripheral  | pin  | Nucleo header | DMA / IRQ          |
//! |-------------------------|--------------------|-------------|------|---------------|--------------------|
//! | trigger out 0           | output 0           | TIM2_CH1    | PA0  | CN8 A0        | DMA1_CH1 (req 56)  |
//! | trigger out 1           | output 1           | TIM2_CH2    | PA1  | CN8 A1        | DMA1_CH2 (req 57)  |
//! | trigger out 2           | output 2           | TIM2_CH3    | PB10 | CN9 D6        | DMA1_CH3 (req 58)  |
//! | trigger out 3           | output 3           | TIM2_CH4    | PB11 | CN10 (morpho) | DMA1_CH4 (req 59)  |
//! | feedback in 0           | feedback 0         | TIM3_CH1    | PC6  | CN10 (morpho) | TIM3 IRQ           |
//! | feedback in 1           | feedback 1         | TIM3_CH2    | PC7  | CN5 D9        | TIM3 IRQ           |
//! | feedback in 2           | feedback 2         | TIM3_CH3    | PC8  | CN10 (morpho) | TIM3 IRQ           |
//! | feedback in 3           | feedback 3         | TIM3_CH4    | PC9  | CN10 (morpho) | TIM3 IRQ           |
//! | status LED (LD2, green) | -                  | GPIO        | PA5  | on board      | -                  |
//! | USB D- / D+             | -                  | USB FS      | PA11 / PA12 | CN10 (morpho) | USB_LP IRQ |
//!
//! Why these pins: PA2/PA3 carry the ST-LINK virtual COM port and PA5 the LED
//! on the Nucleo, so TIM2 CH3/CH4 go to PB10/PB11 and the feedback capture to
//! TIM3 on port C. TIM5 has no pin: it is the 64-bit board clock and its
//! channel-1 compare is the common start strobe of TIM2 and TIM3
//! (timebase.rs). TIM15 is embassy's time driver.

use embassy_stm32::peripherals::{
    DMA1_CH1, DMA1_CH2, DMA1_CH3, DMA1_CH4, IWDG, PA0, PA1, PA11, PA12, PA5, PB10, PB11, PC6, PC7,
    PC8, PC9, TIM2, TIM3, TIM5, USB,
};
use embassy_stm32::{Peri, Peripherals};

/// Trigger output channels: TIM2 CH1..CH4, index = board-core output channel.
pub const TRIGGER_CHANNELS: usize = 4;
/// Feedback input-capture channels: TIM3 CH1..CH4, index = board-core feedback channel.
pub const FEEDBACK_CHANNELS: usize = 4;

// What the board tells the host (`DeviceInfo::limits`, from which the host
// and the board's own validation take how many heads it drives) must be the
// lines wired here: 4 trigger outputs, 4 feedback inputs, so 2 heads of the
// protocol's `MAX_HEADS` = 4. Heads C and D need a second 32-bit timer for
// their triggers; the G474's other one, TIM5, is the board clock.
const _: () = assert!(
    TRIGGER_CHANNELS == protocol::BoardLimits::STM32G474.output_channels as usize
        && FEEDBACK_CHANNELS == protocol::BoardLimits::STM32G474.feedback_channels as usize
        && TRIGGER_CHANNELS <= protocol::limits::MAX_OUTPUT_CHANNELS
);
/// DMAMUX1 request numbers of TIM2_CH1..CH4 (RM0440 table "DMAMUX: assignment
/// of multiplexer inputs to resources"; the same numbers embassy's generated
/// `dma_trait_impl!(timer::Dma<ChN>, TIM2, ..)` lines carry).
pub const TIM2_CC_DMA_REQUEST: [u8; TRIGGER_CHANNELS] = [56, 57, 58, 59];
/// DMA1 channels (0-based: DMA1_CH1 = 0) serving TIM2 CH1..CH4; DMA1 channel
/// `n` is fed by DMAMUX1 channel `n`.
pub const TRIGGER_DMA_CHANNEL: [usize; TRIGGER_CHANNELS] = [0, 1, 2, 3];
/// Whether each feedback line is active-high (DLPC350/DLPC900 trigger-out
/// and a camera's exposure-active output through a non-inverting opto
/// stage); flip an entry for an open-collector output pulled up (active-low).
pub const FEEDBACK_ACTIVE_HIGH: [bool; FEEDBACK_CHANNELS] = [true, true, true, true];
/// GPIOC pin numbers of feedback 0..3 (PC6..PC9), for reading idle levels.
pub const FEEDBACK_PIN_NUMBERS: [usize; FEEDBACK_CHANNELS] = [6, 7, 8, 9];
/// Whether each trigger output is active-high. DLPC350/DLPC900 trigger inputs
/// and opto-isolated camera inputs driven through a series resistor are all
/// active-high; an inverting driver stage would flip its entry.
pub const TRIGGER_ACTIVE_HIGH: [bool; TRIGGER_CHANNELS] = [true, true, true, true];

/// The trigger-output side: sequencing timer, its pins and DMA channels.
pub struct TriggerPins {
    /// 32-bit sequencing timer.
    pub timer: Peri<'static, TIM2>,
    /// Output 0 (TIM2_CH1).
    pub out0: Peri<'static, PA0>,
    /// Output 1 (TIM2_CH2).
    pub out1: Peri<'static, PA1>,
    /// Output 2 (TIM2_CH3).
    pub out2: Peri<'static, PB10>,
    /// Output 3 (TIM2_CH4).
    pub out3: Peri<'static, PB11>,
    /// DMA channels feeding CCR1..CCR4, reserved so nothing else uses them.
    pub dma: (
        Peri<'static, DMA1_CH1>,
        Peri<'static, DMA1_CH2>,
        Peri<'static, DMA1_CH3>,
        Peri<'static, DMA1_CH4>,
    ),
}

/// The feedback side: capture timer and its pins.
pub struct FeedbackPins {
    /// 16-bit capture timer, started together with TIM2.
    pub timer: Peri<'static, TIM3>,
    /// Feedback 0 (TIM3_CH1).
    pub in0: Peri<'static, PC6>,
    /// Feedback 1 (TIM3_CH2).
    pub in1: Peri<'static, PC7>,
    /// Feedback 2 (TIM3_CH3).
    pub in2: Peri<'static, PC8>,
    /// Feedback 3 (TIM3_CH4).
    pub in3: Peri<'static, PC9>,
}

/// USB full-speed device pins (no user USB connector on the Nucleo: wire a
/// breakout to CN10, README.md "USB").
pub struct UsbPins {
    /// The USB FS peripheral.
    pub usb: Peri<'static, USB>,
    /// D+.
    pub dp: Peri<'static, PA12>,
    /// D-.
    pub dm: Peri<'static, PA11>,
}

/// Every peripheral the firmware uses, split by job.
pub struct Pins {
    /// Trigger outputs.
    pub trigger: TriggerPins,
    /// Feedback inputs.
    pub feedback: FeedbackPins,
    /// USB link.
    pub usb: UsbPins,
    /// Status LED LD2.
    pub led: Peri<'static, PA5>,
    /// Independent watchdog.
    pub iwdg: Peri<'static, IWDG>,
    /// Board clock and start strobe (no pin).
    pub timebase: Peri<'static, TIM5>,
}

impl Pins {
    /// Takes each peripheral once out of embassy's singleton set.
    pub fn take(p: Peripherals) -> Self {
        Pins {
            trigger: TriggerPins {
                timer: p.TIM2,
                out0: p.PA0,
                out1: p.PA1,
                out2: p.PB10,
                out3: p.PB11,
                dma: (p.DMA1_CH1, p.DMA1_CH2, p.DMA1_CH3, p.DMA1_CH4),
            },
            feedback: FeedbackPins {
                timer: p.TIM3,
                in0: p.PC6,
                in1: p.PC7,
                in2: p.PC8,
                in3: p.PC9,
            },
            usb: UsbPins {
                usb: p.USB,
                dp: p.PA12,
                dm: p.PA11,
            },
            led: p.PA5,
            iwdg: p.IWDG,
            timebase: p.TIM5,
        }
    }
}
