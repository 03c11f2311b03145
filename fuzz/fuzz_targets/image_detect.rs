//! Image decoding plus board detection: any bytes, as a PNG or JPEG file a user might pass to
//! `hvs board detect`, decode or fail with an error, and a decoded image of any size and
//! content is detected or refused with a reason, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(reader) = image::ImageReader::new(std::io::Cursor::new(data)).with_guessed_format()
    else {
        return;
    };
    let mut reader = reader;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(2048);
    limits.max_image_height = Some(2048);
    limits.max_alloc = Some(64 << 20);
    reader.limits(limits);
    let Ok(img) = reader.decode() else {
        return;
    };
    let grey = hvs_vision::detect::to_grey(&img);
    for (cols, rows) in [(9, 6), (3, 2)] {
        let board = hvs_vision::board::Board::new(cols, rows, 6.0).expect("a valid board");
        let _ = hvs_vision::detect::detect(&grey, &board);
    }
});
