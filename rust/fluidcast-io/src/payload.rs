//! Binary payloads of VTK XML arrays: headers checked before anything is allocated.
//!
//! Layouts (VTK's `vtkXMLDataElement` conventions): uncompressed = `[nbytes][data]`;
//! compressed = `[nblocks][block size][last block size][compressed size]*nblocks [blocks]`,
//! where a last block size of 0 means the last block is full (VTK writes this whenever the
//! array size is an exact multiple of the block size). Header words are UInt32 or UInt64
//! (`header_type`), in the file's byte order.
//!
//! Every size read from a header is checked, with checked arithmetic, against what the XML
//! declares (`NumberOfPoints` × components × type size) and against the bytes the file really
//! holds before a buffer is allocated; decompression streams into a buffer that refuses to
//! grow past the size the header states, so a lying header or a compression bomb is an error,
//! never an allocation of what the file merely claims.

use rayon::prelude::*;
use std::io::Write;

use base64::Engine;

use crate::ScalarType;

/// The compression VTK applied to binary arrays (`compressor` attribute of `<VTKFile>`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Compressor {
    Zlib,
    Lz4,
    Lzma,
}

/// How binary payloads of one file are laid out.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Ctx {
    pub big_endian: bool,
    /// `header_type`: UInt32 or UInt64.
    pub header: ScalarType,
    pub compressor: Option<Compressor>,
}

/// lz4's largest expansion: one token byte can stand for at most 255 output bytes plus
/// a 4-byte minimum match, so output ≤ 255 × input + 16 bounds every valid block.
const LZ4_MAX_RATIO: usize = 255;

impl Ctx {
    /// Bytes per header word.
    fn hb(&self) -> usize {
        self.header.size()
    }

    /// Header word `i` of `b`, as a `usize` (a value above `usize::MAX` saturates, which
    /// every later size check then rejects).
    fn word(&self, b: &[u8], i: usize) -> Option<usize> {
        let hb = self.hb();
        let s = b.get(i.checked_mul(hb)?..i.checked_add(1)?.checked_mul(hb)?)?;
        let v = if let Ok(a) = <[u8; 4]>::try_from(s) {
            u64::from(if self.big_endian {
                u32::from_be_bytes(a)
            } else {
                u32::from_le_bytes(a)
            })
        } else {
            let a = <[u8; 8]>::try_from(s).ok()?;
            if self.big_endian {
                u64::from_be_bytes(a)
            } else {
                u64::from_le_bytes(a)
            }
        };
        Some(usize::try_from(v).unwrap_or(usize::MAX))
    }
}

/// Checks a header's total size against the size the XML declares for the array.
fn check_declared(what: &str, found: usize, expected: Option<usize>) -> Result<(), String> {
    match expected {
        Some(e) if e != found => Err(format!(
            "{what} says {found} bytes but the array needs {e} (tuples × components × type \
             size); a wrong header_type or NumberOfPoints, or a damaged file"
        )),
        _ => Ok(()),
    }
}

/// A writer into a `Vec` that refuses to hold more than `cap` bytes: decompression stops
/// with an error as soon as a block produces more than its header says.
struct Capped<'a> {
    out: &'a mut Vec<u8>,
    cap: usize,
}

impl Write for Capped<'_> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        if buf.len() > self.cap.saturating_sub(self.out.len()) {
            return Err(std::io::Error::other(
                "the block decompresses to more bytes than its header states",
            ));
        }
        self.out.extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// Decompresses one block, which must give exactly `size` bytes, appending to `out`.
fn decompress_into(
    c: Compressor,
    data: &[u8],
    size: usize,
    out: &mut Vec<u8>,
) -> Result<(), String> {
    let start = out.len();
    let cap = start.saturating_add(size);
    match c {
        Compressor::Zlib => {
            let mut w = Capped { out, cap };
            std::io::copy(&mut flate2::read::ZlibDecoder::new(data), &mut w)
                .map_err(|e| format!("zlib block: {e}"))?;
        }
        Compressor::Lz4 => {
            // A valid block cannot expand more than LZ4_MAX_RATIO: never allocate more.
            let bound = data.len().saturating_mul(LZ4_MAX_RATIO).saturating_add(16);
            if size > bound {
                return Err(format!(
                    "an lz4 block of {} bytes cannot hold the {size} bytes its header states",
                    data.len()
                ));
            }
            out.resize(cap, 0);
            let n = lz4_flex::block::decompress_into(data, out.get_mut(start..).unwrap_or(&mut []))
                .map_err(|e| format!("lz4 block: {e}"))?;
            out.truncate(start.saturating_add(n));
        }
        Compressor::Lzma => {
            let mut w = Capped { out, cap };
            lzma_rs::xz_decompress(&mut std::io::Cursor::new(data), &mut w)
                .map_err(|e| format!("lzma block: {e}"))?;
        }
    }
    let got = out.len().saturating_sub(start);
    if got != size {
        return Err(format!(
            "a compressed block gave {got} bytes, its header says {size}"
        ));
    }
    Ok(())
}

/// The header of a compressed array, validated.
struct BlockHeader {
    block_size: usize,
    last_size: usize,
    compressed: Vec<usize>,
}

impl BlockHeader {
    /// Number of blocks in the header starting at `b`; refused when the blocks' size words
    /// alone could not fit in `avail` bytes of the file.
    fn count(b: &[u8], ctx: Ctx, avail: usize) -> Result<usize, String> {
        let nb = ctx.word(b, 0).ok_or("compression header is truncated")?;
        if nb > avail / ctx.hb() {
            return Err(format!(
                "compression header claims {nb} blocks, more than the file holds"
            ));
        }
        Ok(nb)
    }

    /// Header length in bytes for `nb` blocks (cannot overflow: `nb` ≤ file length).
    fn len_for(nb: usize, ctx: Ctx) -> usize {
        nb.saturating_add(3).saturating_mul(ctx.hb())
    }

    /// Parses and checks the header at the start of `b`; `expected` is the array's size
    /// from the XML, when known.
    fn parse(b: &[u8], ctx: Ctx, expected: Option<usize>) -> Result<BlockHeader, String> {
        let short = || "compression header is truncated".to_string();
        let nb = Self::count(b, ctx, b.len())?;
        let block_size = ctx.word(b, 1).ok_or_else(short)?;
        let last = ctx.word(b, 2).ok_or_else(short)?;
        let last_size = if last == 0 { block_size } else { last };
        if nb > 0 && last_size > block_size {
            return Err(format!(
                "compression header: last block of {last_size} bytes is larger than the block \
                 size {block_size}"
            ));
        }
        let total = match nb {
            0 => 0,
            n => (n - 1)
                .checked_mul(block_size)
                .and_then(|t| t.checked_add(last_size))
                .ok_or_else(|| {
                    format!("compression header: {n} blocks of {block_size} bytes overflow")
                })?,
        };
        check_declared("compression header", total, expected)?;
        let compressed = (0..nb)
            .map(|i| ctx.word(b, 3 + i).ok_or_else(short))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(BlockHeader {
            block_size,
            last_size,
            compressed,
        })
    }

    fn total_compressed(&self) -> Result<usize, String> {
        self.compressed
            .iter()
            .try_fold(0usize, |a, &c| a.checked_add(c))
            .ok_or_else(|| "compressed block sizes overflow".to_string())
    }

    /// The blocks' compressed bytes, checked to be present in `data`: what a buffer may be
    /// reserved from (never from the header's claim alone).
    fn present(&self, data: &[u8]) -> Result<usize, String> {
        let total_c = self.total_compressed()?;
        if total_c > data.len() {
            return Err(format!(
                "compressed blocks need {total_c} bytes, the file holds {} (file truncated?)",
                data.len()
            ));
        }
        Ok(total_c)
    }

    /// Decompresses all blocks of `data` (which must hold them all).
    fn inflate(&self, data: &[u8], c: Compressor) -> Result<Vec<u8>, String> {
        // Reserve from the bytes present, never from the header's claim; the vector grows as
        // real data arrives, capped per block.
        let mut out = Vec::with_capacity(self.present(data)?.saturating_mul(4));
        self.inflate_each(data, c, |block| {
            out.extend_from_slice(block);
            Ok(())
        })?;
        Ok(out)
    }

    /// Decompresses all blocks of `data` straight into values of type `st`: no buffer of
    /// the whole array's bytes beside the values (a value may straddle two blocks).
    fn inflate_values(
        &self,
        data: &[u8],
        c: Compressor,
        st: ScalarType,
        big_endian: bool,
    ) -> Result<Vec<f64>, String> {
        let size = st.size();
        let mut out = Vec::with_capacity(self.present(data)?.saturating_mul(4) / size);
        let mut carry: Vec<u8> = Vec::with_capacity(size);
        let mut total = 0usize;
        self.inflate_each(data, c, |block| {
            total += block.len();
            let mut rest = block;
            if !carry.is_empty() {
                let take = size.saturating_sub(carry.len()).min(rest.len());
                let (head, tail) = rest.split_at_checked(take).unwrap_or((rest, &[]));
                carry.extend_from_slice(head);
                rest = tail;
                if carry.len() == size {
                    st.decode_into(&carry, big_endian, &mut out)?;
                    carry.clear();
                }
            }
            let whole = rest.len() - rest.len() % size;
            let (values, left) = rest.split_at_checked(whole).unwrap_or((&[], rest));
            st.decode_into(values, big_endian, &mut out)?;
            carry.extend_from_slice(left);
            Ok(())
        })?;
        if !carry.is_empty() {
            return Err(format!(
                "{total} bytes are not a whole number of {} values",
                st.vtk_name()
            ));
        }
        Ok(out)
    }

    /// Decompresses all blocks of `data` (which must hold them all), handing each to `sink`
    /// in order. Blocks are independent: a batch of them is decompressed in parallel, each
    /// into its own buffer.
    fn inflate_each(
        &self,
        data: &[u8],
        c: Compressor,
        mut sink: impl FnMut(&[u8]) -> Result<(), String>,
    ) -> Result<(), String> {
        let nb = self.compressed.len();
        self.present(data)?;
        let mut spans = Vec::with_capacity(nb);
        let mut pos = 0usize;
        for &cs in &self.compressed {
            spans.push((pos, cs));
            pos += cs;
        }
        let batch = rayon::current_num_threads().max(1) * 8;
        for (b, chunk) in spans.chunks(batch).enumerate() {
            let blocks: Vec<Result<Vec<u8>, String>> = chunk
                .par_iter()
                .enumerate()
                .map(|(k, &(at, cs))| {
                    let i = b * batch + k;
                    let blk = data.get(at..at + cs).ok_or_else(|| {
                        format!("compressed block {i} of {nb} runs past the data")
                    })?;
                    let size = if i + 1 == nb {
                        self.last_size
                    } else {
                        self.block_size
                    };
                    let mut one = Vec::with_capacity(cs.saturating_mul(4).min(size));
                    decompress_into(c, blk, size, &mut one)?;
                    Ok(one)
                })
                .collect();
            for one in blocks {
                sink(&one?)?;
            }
        }
        Ok(())
    }
}

/// Decodes one raw binary payload (header + data) starting at `src`. `expected` is the
/// array's byte size from the XML, when known. Returns the bytes and how many bytes of
/// `src` the payload took.
pub(crate) fn decode_raw(
    src: &[u8],
    ctx: Ctx,
    expected: Option<usize>,
) -> Result<(std::borrow::Cow<'_, [u8]>, usize), String> {
    match ctx.compressor {
        None => {
            let n = ctx.word(src, 0).ok_or("data header is truncated")?;
            check_declared("data header", n, expected)?;
            let hb = ctx.hb();
            let avail = src.len().saturating_sub(hb);
            if n > avail {
                return Err(format!(
                    "data header says {n} bytes but only {avail} follow (file truncated?)"
                ));
            }
            // Uncompressed: the bytes as they lie in the file, not a copy of them.
            Ok((src.get(hb..hb + n).unwrap_or_default().into(), hb + n))
        }
        Some(c) => {
            let h = BlockHeader::parse(src, ctx, expected)?;
            let hl = BlockHeader::len_for(h.compressed.len(), ctx);
            let data = h.inflate(src.get(hl..).unwrap_or_default(), c)?;
            Ok((data.into(), hl + h.total_compressed()?))
        }
    }
}

/// Decodes one raw binary payload (header + data) starting at `src` into values of type
/// `st`, as [`decode_raw`] and [`ScalarType::decode`] would together, without the whole
/// array's decompressed bytes beside the values. Returns them and how many bytes of `src`
/// the payload took.
pub(crate) fn decode_raw_values(
    src: &[u8],
    ctx: Ctx,
    expected: Option<usize>,
    st: ScalarType,
) -> Result<(Vec<f64>, usize), String> {
    match ctx.compressor {
        None => {
            let (bytes, used) = decode_raw(src, ctx, expected)?;
            Ok((st.decode(&bytes, ctx.big_endian)?, used))
        }
        Some(c) => {
            let h = BlockHeader::parse(src, ctx, expected)?;
            let hl = BlockHeader::len_for(h.compressed.len(), ctx);
            let data = src.get(hl..).unwrap_or_default();
            let values = h.inflate_values(data, c, st, ctx.big_endian)?;
            Ok((values, hl + h.total_compressed()?))
        }
    }
}

fn b64(text: &[u8]) -> Result<Vec<u8>, String> {
    base64::engine::general_purpose::STANDARD
        .decode(text)
        .map_err(|e| format!("invalid base64: {e}"))
}

/// Characters of base64 text that encode `nbytes` bytes (callers keep `nbytes` ≤ the text
/// length, so this cannot overflow).
fn b64_chars(nbytes: usize) -> usize {
    nbytes.div_ceil(3).saturating_mul(4)
}

/// `len` characters of `text` from `from`, or a truncation error.
fn b64_slice(text: &[u8], from: usize, len: usize) -> Result<&[u8], String> {
    from.checked_add(len)
        .and_then(|end| text.get(from..end))
        .ok_or_else(|| {
            format!(
                "base64 data needs {len} characters from character {from}, the file holds {} \
                 (file truncated?)",
                text.len().saturating_sub(from)
            )
        })
}

/// Decodes a base64 payload (header + data). VTK encodes header and data either as one
/// base64 stream or as two separately padded ones (VTK's compressed arrays, pyvisfile's
/// version 0.1 files); the two differ only where the header's last quantum holds padding.
/// Returns the bytes and how many characters of `text` the payload took.
pub(crate) fn decode_base64(
    text: &[u8],
    ctx: Ctx,
    expected: Option<usize>,
) -> Result<(Vec<u8>, usize), String> {
    let hb = ctx.hb();
    let Some(c) = ctx.compressor else {
        let hc = b64_chars(hb);
        let head = b64(b64_slice(text, 0, hc)?)?;
        let n = ctx.word(&head, 0).ok_or("data header is truncated")?;
        check_declared("data header", n, expected)?;
        // Every byte takes more than one base64 character: n beyond the text is a lie.
        if n > text.len() {
            return Err(format!(
                "data header says {n} bytes but the base64 text holds only {} characters \
                 (file truncated?)",
                text.len()
            ));
        }
        let separate = !hb.is_multiple_of(3) && text.get(hc - 1) == Some(&b'=');
        return if separate {
            Ok((b64(b64_slice(text, hc, b64_chars(n))?)?, hc + b64_chars(n)))
        } else {
            let all = b64(b64_slice(text, 0, b64_chars(hb + n))?)?;
            Ok((
                all.get(hb..hb + n).unwrap_or_default().to_vec(),
                b64_chars(hb + n),
            ))
        };
    };
    // The first three words take exactly 4*hb characters (3*hb bytes, no padding).
    let first = b64(b64_slice(text, 0, 4 * hb)?)?;
    let nb = BlockHeader::count(&first, ctx, text.len())?;
    let hlen = BlockHeader::len_for(nb, ctx);
    let hc = b64_chars(hlen);
    let separate = hlen.is_multiple_of(3) || text.get(hc.saturating_sub(1)) == Some(&b'=');
    let header_bytes = b64(b64_slice(text, 0, hc)?)?;
    let h = BlockHeader::parse(&header_bytes, ctx, expected)?;
    let total = h.total_compressed()?;
    if total > text.len() {
        return Err(format!(
            "compressed blocks need {total} bytes, the base64 text holds only {} characters \
             (file truncated?)",
            text.len()
        ));
    }
    let (data, used) = if separate {
        (
            b64(b64_slice(text, hc, b64_chars(total))?)?,
            hc + b64_chars(total),
        )
    } else {
        let all = b64(b64_slice(text, 0, b64_chars(hlen + total))?)?;
        (
            all.get(hlen..).unwrap_or_default().to_vec(),
            b64_chars(hlen + total),
        )
    };
    Ok((h.inflate(&data, c)?, used))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A zlib payload as VTK writes it (UInt32 header, little endian): `bytes` in blocks of
    /// `block` bytes.
    fn zlib_payload(bytes: &[u8], block: usize) -> Vec<u8> {
        let blocks: Vec<Vec<u8>> = bytes
            .chunks(block)
            .map(|b| {
                let mut e =
                    flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::fast());
                e.write_all(b).unwrap();
                e.finish().unwrap()
            })
            .collect();
        let last = bytes.len() % block;
        let mut out = Vec::new();
        for w in [blocks.len(), block, last] {
            out.extend_from_slice(&(w as u32).to_le_bytes());
        }
        for b in &blocks {
            out.extend_from_slice(&(b.len() as u32).to_le_bytes());
        }
        for b in &blocks {
            out.extend_from_slice(b);
        }
        out
    }

    fn ctx() -> Ctx {
        Ctx {
            big_endian: false,
            header: ScalarType::U32,
            compressor: Some(Compressor::Zlib),
        }
    }

    /// Values that straddle blocks (blocks of 12, 13 and 1 bytes for 8-byte doubles) decode
    /// as the whole array's bytes do; a partial value at the end is an error.
    #[test]
    fn values_decode_straight_from_blocks_that_split_them() {
        let values: Vec<f64> = (0..101).map(|i| i as f64 * 0.37 - 5.0).collect();
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        for block in [1, 12, 13, 64, 4096] {
            let p = zlib_payload(&bytes, block);
            let (got, used) =
                decode_raw_values(&p, ctx(), Some(bytes.len()), ScalarType::F64).unwrap();
            assert_eq!(got, values, "blocks of {block}");
            assert_eq!(used, p.len());
            let (raw, _) = decode_raw(&p, ctx(), Some(bytes.len())).unwrap();
            assert_eq!(ScalarType::F64.decode(&raw, false).unwrap(), got);
        }
        // A header whose compressed sizes claim 2.6 GB the payload does not hold: refused
        // before anything is reserved from the claim.
        let mut lying = zlib_payload(&bytes, 64);
        lying[12..16].copy_from_slice(&(u32::MAX / 2).to_le_bytes());
        let e = decode_raw_values(&lying, ctx(), None, ScalarType::F64).unwrap_err();
        assert!(e.contains("the file holds"), "{e}");
        let short = &bytes[..bytes.len() - 3];
        let p = zlib_payload(short, 12);
        let e = decode_raw_values(&p, ctx(), None, ScalarType::F64).unwrap_err();
        assert!(
            e.contains("805 bytes are not a whole number of Float64 values"),
            "{e}"
        );
    }
}
