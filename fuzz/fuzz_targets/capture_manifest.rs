//! Any bytes as a capture manifest (`reconstruct`'s `capture.json`), for a small
//! projector: no panic; a description that reads has as many projector images as it
//! counts frames, and decoding those images (the camera seeing the projector) never
//! panics whatever the description says.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slscan::capture::decode::decode;
use slscan::capture::manifest::parse;
use slscan::capture::patterns::projector_images;

const PROJECTOR: (u32, u32) = (48, 16);

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(spec) = parse(text, PROJECTOR) else {
        return;
    };
    let frames = spec.frame_count();
    if frames > 96 {
        return;
    }
    let images = projector_images(&spec, PROJECTOR.0, PROJECTOR.1);
    assert_eq!(images.len(), frames);
    let refs: Vec<_> = images.iter().collect();
    if let Ok(axes) = decode(&spec, &refs, PROJECTOR, 0.01) {
        for a in axes {
            assert_eq!(a.coord_px.data.len(), (PROJECTOR.0 * PROJECTOR.1) as usize);
        }
    }
});
