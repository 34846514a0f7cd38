//! LZF decompression (the codec of PCD's `binary_compressed`), checked: corrupt input is an
//! error, never an out-of-bounds access.

/// Decompresses `input` into exactly `expected_len` bytes. The declared length only bounds the
/// output; memory is reserved for what `input` can expand to (at most 88 bytes per byte).
pub fn decompress(input: &[u8], expected_len: usize) -> Result<Vec<u8>, String> {
    let mut out: Vec<u8> = Vec::with_capacity(expected_len.min(input.len().saturating_mul(88)));
    let mut i = 0;
    while i < input.len() {
        let ctrl = input[i] as usize;
        i += 1;
        if ctrl < 32 {
            // A literal run of ctrl + 1 bytes.
            let run = input
                .get(i..i + ctrl + 1)
                .ok_or("LZF literal run past the end of the data")?;
            out.extend_from_slice(run);
            i += ctrl + 1;
        } else {
            // A back reference: length in the top 3 bits (7 = read one more byte).
            let mut len = ctrl >> 5;
            if len == 7 {
                len += *input
                    .get(i)
                    .ok_or("LZF data ends inside a back reference")?
                    as usize;
                i += 1;
            }
            let low = *input
                .get(i)
                .ok_or("LZF data ends inside a back reference")? as usize;
            i += 1;
            let back = ((ctrl & 0x1f) << 8) + low + 1;
            let start = out
                .len()
                .checked_sub(back)
                .ok_or("LZF back reference before the start of the data")?;
            for k in 0..len + 2 {
                let b = out[start + k];
                out.push(b);
            }
        }
        if out.len() > expected_len {
            return Err(format!(
                "LZF data decompresses past the declared {expected_len} bytes"
            ));
        }
    }
    if out.len() != expected_len {
        return Err(format!(
            "LZF data decompresses to {} bytes, the header declares {expected_len}",
            out.len()
        ));
    }
    Ok(out)
}

/// Compresses `input` as LZF with literal runs only (valid LZF that any decoder reads; used
/// to write test files, not for size, so hidden from the docs).
#[doc(hidden)]
pub fn compress_literal(input: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(input.len() + input.len() / 32 + 1);
    for chunk in input.chunks(32) {
        out.push((chunk.len() - 1) as u8);
        out.extend_from_slice(chunk);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn literals_and_overlapping_back_references_decode() {
        // "abc" then a back reference of length 6 at distance 3: "abcabcabc".
        let data = [2, b'a', b'b', b'c', (4 << 5), 2];
        assert_eq!(decompress(&data, 9).unwrap(), b"abcabcabc");
        let text: Vec<u8> = (0..100u8).collect();
        assert_eq!(decompress(&compress_literal(&text), 100).unwrap(), text);
    }

    #[test]
    fn corrupt_data_is_an_error() {
        assert!(decompress(&[5, 1, 2], 6).is_err(), "short literal");
        assert!(
            decompress(&[(1 << 5), 10], 3).is_err(),
            "reference before start"
        );
        assert!(decompress(&[0, 1], 2).is_err(), "length mismatch");
        assert!(decompress(&[0xe0], 9).is_err(), "truncated reference");
    }
}
