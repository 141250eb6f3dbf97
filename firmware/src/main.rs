//! The slscan sync board: board-core's sequencer on an STM32G474
//! (NUCLEO-G474RE), trigger edges from timer compare + DMA.
//!
//! ```text
//! USB CDC-ACM <-> usb_link (board_core::Link: framing, dispatch, sequencer)
//!                    |  TriggerHardware
//!                    v
//!             board::g474::hardware: TIM5 clock/strobe, TIM2+DMA edges, TIM3 feedback
//! status_led (LD2)   watchdog (IWDG)
//! ```
//!
//! This file only wires: init, take each peripheral once, move owned
//! drivers into tasks. Setup and flashing: README.md.
#![no_std]
#![no_main]

mod board;
mod dma_table;
mod status_led;
mod tick_extend;
mod usb_link;
mod watchdog;

use board_core::Link;
use embassy_executor::Spawner;
use embassy_stm32::peripherals::USB;
use embassy_stm32::usb::Driver;
use embassy_usb::class::cdc_acm::{CdcAcmClass, State};
use embassy_usb::{Builder, UsbDevice};
use protocol::{BoardLimits, DeviceInfo, FirmwareVersion, PROTOCOL_VERSION};
use static_cell::StaticCell;
use {defmt_rtt as _, panic_probe as _};

use crate::board::active::timers::{DmaBuffers, MAX_EDGES_PER_CHANNEL};
use crate::board::active::{self as chip, pins::TRIGGER_CHANNELS};

/// pid.codes test VID/PID (https://pid.codes/1209/0001/): replace for a product.
const USB_VID: u16 = 0x1209;
const USB_PID: u16 = 0x0001;

static DMA_BUFFERS: StaticCell<DmaBuffers> = StaticCell::new();
static LINK: StaticCell<Link> = StaticCell::new();
static USB_CONFIG_DESC: StaticCell<[u8; 256]> = StaticCell::new();
static USB_BOS_DESC: StaticCell<[u8; 256]> = StaticCell::new();
static USB_CONTROL_BUF: StaticCell<[u8; 64]> = StaticCell::new();
static CDC_STATE: StaticCell<State> = StaticCell::new();
static USB_HANDLER: StaticCell<usb_link::UsbStateHandler> = StaticCell::new();
static USB_SERIAL: StaticCell<heapless::String<16>> = StaticCell::new();

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    let buffers = DMA_BUFFERS.init([[0; MAX_EDGES_PER_CHANNEL]; TRIGGER_CHANNELS]);
    let board = chip::init(buffers);

    let info = DeviceInfo {
        protocol_version: PROTOCOL_VERSION,
        firmware_version: firmware_version(),
        board_id: board.board_id,
        limits: BoardLimits::STM32G474,
        reset_cause: board.reset_cause,
    };
    let link = LINK.init_with(|| Link::new(info));

    let (device, class) = usb_cdc(board.usb, board.board_id);
    spawner.spawn(defmt::unwrap!(usb_device(device)));
    spawner.spawn(defmt::unwrap!(usb_link::run(class, board.hardware, link)));
    spawner.spawn(defmt::unwrap!(status_led::run(board.led)));
    spawner.spawn(defmt::unwrap!(watchdog::run(board.watchdog)));
    defmt::info!("tasks running");
}

/// The USB device with one CDC-ACM function.
/// The board id as the USB serial number, so hosts tell boards apart
/// (`/dev/serial/by-id/...`).
fn usb_cdc(
    driver: Driver<'static, USB>,
    board_id: u64,
) -> (UsbDevice<'static, Driver<'static, USB>>, usb_link::Class) {
    let mut config = embassy_usb::Config::new(USB_VID, USB_PID);
    config.manufacturer = Some("slscan");
    config.product = Some("slscan sync board");
    config.serial_number = Some(USB_SERIAL.init(hex16(board_id)));
    config.max_power = 100;
    config.max_packet_size_0 = 64;
    let mut builder = Builder::new(
        driver,
        config,
        USB_CONFIG_DESC.init([0; 256]),
        USB_BOS_DESC.init([0; 256]),
        &mut [], // no Microsoft OS descriptors
        USB_CONTROL_BUF.init([0; 64]),
    );
    builder.handler(USB_HANDLER.init(usb_link::UsbStateHandler));
    let class = CdcAcmClass::new(
        &mut builder,
        CDC_STATE.init(State::new()),
        usb_link::USB_PACKET_BYTES as u16,
    );
    (builder.build(), class)
}

/// `value` as 16 upper-case hex digits.
fn hex16(value: u64) -> heapless::String<16> {
    let mut out = heapless::String::new();
    for shift in (0..16).rev() {
        let digit = ((value >> (shift * 4)) & 0xF) as u8;
        let c = char::from(if digit < 10 {
            b'0' + digit
        } else {
            b'A' + digit - 10
        });
        // 16 pushes into a 16-byte string cannot fail.
        let _ = out.push(c);
    }
    out
}

/// The package version, parsed at compile time.
fn firmware_version() -> FirmwareVersion {
    const fn parse(s: &str) -> u16 {
        let b = s.as_bytes();
        let mut v = 0u16;
        let mut i = 0;
        while i < b.len() {
            v = v * 10 + (b[i] - b'0') as u16;
            i += 1;
        }
        v
    }
    FirmwareVersion {
        major: parse(env!("CARGO_PKG_VERSION_MAJOR")),
        minor: parse(env!("CARGO_PKG_VERSION_MINOR")),
        patch: parse(env!("CARGO_PKG_VERSION_PATCH")),
    }
}

/// Runs the USB device state machine (enumeration, control requests).
#[embassy_executor::task]
async fn usb_device(mut device: UsbDevice<'static, Driver<'static, USB>>) {
    device.run().await
}
