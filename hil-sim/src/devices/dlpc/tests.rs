use super::*;
use protocol::ProjectorModel;

fn limits(dmd: (u16, u16)) -> ControllerLimits {
    ControllerLimits {
        dmd_px: dmd,
        ..ProjectorModel::Dlpc900.controller()
    }
}

/// A write message with reply wanted, split into reports by hand (not
/// the host's framing code).
fn send(sim: &mut DlpcSim, seq: u8, command: u16, data: &[u8]) -> [u8; 64] {
    let mut text = command.to_le_bytes().to_vec();
    text.extend_from_slice(data);
    let mut first = vec![0u8, 0x40, seq];
    first.extend_from_slice(&(text.len() as u16).to_le_bytes());
    first.extend(text.iter().take(60));
    first.resize(65, 0);
    sim.write(&first).unwrap();
    for chunk in text[text.len().min(60)..].chunks(64) {
        let mut r = vec![0u8];
        r.extend_from_slice(chunk);
        r.resize(65, 0);
        sim.write(&r).unwrap();
    }
    sim.read().unwrap().expect("a reply")
}

fn erle_two_rows_alike() -> Vec<u8> {
    let mut img = b"Spld".to_vec();
    img.extend_from_slice(&[3, 0, 2, 0, 0, 0, 0, 0]);
    img.extend_from_slice(&[0xFF; 8]);
    img.extend_from_slice(&[0; 5]);
    img.extend_from_slice(&[2, 1]);
    img.extend_from_slice(&[0; 21]);
    // Row 0: pixel 0x000102 twice, then one literal 0x0000FF; row 1 copies.
    img.extend_from_slice(&[2, 0, 1, 2, 1, 0, 0, 0xFF, 0, 0, 0, 1, 3, 0, 0, 0, 1, 0]);
    img
}

#[test]
fn erle_decodes_runs_literals_and_copied_rows_and_refuses_short_rows() {
    let img = erle_two_rows_alike();
    let words = decode_dlpc900_image(&img, (3, 2)).unwrap();
    assert_eq!(words, vec![0x0102, 0x0102, 0xFF, 0x0102, 0x0102, 0xFF]);
    let mut short = img.clone();
    short[48] = 1; // the first run now covers one pixel: row 0 is 2 wide
    assert!(decode_dlpc900_image(&short, (3, 2)).is_err());
    assert!(decode_dlpc900_image(&img[..60], (3, 2)).is_err());
    assert_eq!(decode_dlpc900_image(&img, (4, 2)), Err(ImageError::Header));
}

#[test]
fn dlpc900_on_the_fly_upload_runs_and_shows_the_lut_in_order() {
    let mut sim = DlpcSim::new(DlpcKind::Dlpc900, limits((3, 2)));
    let img = erle_two_rows_alike();
    // Start before anything is valid: refused, error code 5.
    assert_eq!(send(&mut sim, 1, 0x1A24, &[2])[0] & 0x20, 0x20);
    let mut read = vec![0u8, 0xC0, 2, 2, 0, 0x00, 0x01];
    read.resize(65, 0);
    sim.write(&read).unwrap();
    assert_eq!(sim.read().unwrap().unwrap()[4], ERR_NOT_ALLOWED);
    // Two 8-bit patterns at bits 0 and 8 of image 0, 5000 us, white.
    for (k, bit) in [(0u16, 0u16), (1, 8)] {
        let e = 5000u32.to_le_bytes();
        let place = (bit << 11).to_le_bytes();
        let entry = [
            k as u8, 0, e[0], e[1], e[2], 0xFF, 0, 0, 0, 0, place[0], place[1],
        ];
        assert_eq!(send(&mut sim, 3, 0x1A34, &entry)[0] & 0x20, 0);
    }
    send(&mut sim, 4, 0x1A31, &[2, 0, 0, 0, 0, 0]);
    let mut init = 0u16.to_le_bytes().to_vec();
    init.extend_from_slice(&(img.len() as u32).to_le_bytes());
    send(&mut sim, 5, 0x1A2A, &init);
    let mut load = (img.len() as u16).to_le_bytes().to_vec();
    load.extend_from_slice(&img);
    assert_eq!(send(&mut sim, 6, 0x1A2B, &load)[0] & 0x20, 0);
    send(&mut sim, 7, 0x1A1A, &[0]);
    assert_eq!(send(&mut sim, 8, 0x1A24, &[2])[0] & 0x20, 0);
    let shown = sim.sequence();
    assert_eq!(shown.len(), 2);
    assert_eq!(shown[0].values[0], 2.0 / 255.0);
    assert_eq!(shown[1].values[0], 1.0 / 255.0);
    assert_eq!(shown[0].values[2], 1.0);
    assert_eq!(shown[0].led, [true; 3]);
    // While it runs, the LUT cannot change.
    assert_eq!(
        send(&mut sim, 9, 0x1A31, &[1, 0, 0, 0, 0, 0])[0] & 0x20,
        0x20
    );
}

#[test]
fn an_exposure_under_the_minimum_fails_validation() {
    let mut sim = DlpcSim::new(DlpcKind::Dlpc900, limits((3, 2)));
    let e = 100u32.to_le_bytes();
    let entry = [0, 0, e[0], e[1], e[2], 0xFF, 0, 0, 0, 0, 0, 0];
    send(&mut sim, 1, 0x1A34, &entry);
    send(&mut sim, 2, 0x1A31, &[1, 0, 0, 0, 0, 0]);
    send(&mut sim, 3, 0x1A1A, &[0]);
    let mut read = vec![0u8, 0xC0, 4, 2, 0, 0x1A, 0x1A];
    read.resize(65, 0);
    sim.write(&read).unwrap();
    // Exposure (bit 0) and a missing image (bit 3).
    assert_eq!(sim.read().unwrap().unwrap()[4], 0x09);
}

#[test]
fn unplugged_mid_message_it_answers_nothing_and_forgets_its_images() {
    let mut sim = DlpcSim::new(DlpcKind::Dlpc900, limits((3, 2)));
    sim.unplug_after(1);
    let mut first = vec![0u8, 0x40, 1, 100, 0, 0x2B, 0x1A];
    first.resize(65, 0);
    sim.write(&first).unwrap();
    assert_eq!(sim.write(&[0u8; 65]), Err(Unplugged));
    assert_eq!(sim.read(), Err(Unplugged));
    assert!(sim.sequence().is_empty());
}
