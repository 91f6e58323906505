//! The codecs of OpenVDB's compressed buffers: zlib (flate2), and blosc 1
//! with its blosclz, LZ4 and zlib codecs (c-blosc 1.x, `blosc/blosc.c`,
//! `blosc/blosclz.c`; the LZ4 block format).

use super::VdbReadError;

pub(super) enum CodecError {
    Unsupported(String),
    Corrupt(String),
}

/// zlib to exactly `expected` bytes, as Compression.cc unzipFromStream:
/// uncompress() into a buffer of that size, which must come out full.
pub(super) fn zlib_decode(src: &[u8], expected: usize) -> std::result::Result<Vec<u8>, CodecError> {
    let mut out = vec![0u8; expected];
    let mut z = flate2::Decompress::new(true);
    loop {
        let (i, o) = (z.total_in() as usize, z.total_out() as usize);
        let status = z
            .decompress(&src[i.min(src.len())..], &mut out[o.min(expected)..], flate2::FlushDecompress::Finish)
            .map_err(|e| CodecError::Corrupt(format!("a zip block does not decompress: {e}")))?;
        let done = z.total_out() as usize >= expected || status == flate2::Status::StreamEnd;
        if done || (z.total_in() as usize == i && z.total_out() as usize == o) {
            break;
        }
    }
    if z.total_out() as usize != expected {
        return Err(CodecError::Corrupt(format!("a zip block decompresses to {} bytes where {expected} were expected", z.total_out())));
    }
    Ok(out)
}

/// Decompress one blosc 1 chunk (c-blosc `blosc_decompress`), which must
/// hold exactly `expected_len` bytes. Compressors: blosclz, LZ4 (and
/// LZ4HC, the same format), zlib; byte shuffle. Refused: snappy, zstd,
/// bit shuffle, and blosc 2's format. Public for the tests that compare it
/// with libblosc.
pub fn blosc_decompress(chunk: &[u8], expected_len: usize) -> std::result::Result<Vec<u8>, VdbReadError> {
    blosc_decode(chunk, expected_len).map_err(|e| match e {
        CodecError::Unsupported(what) => VdbReadError::UnsupportedCompression { grid: None, offset: 0, what },
        CodecError::Corrupt(what) => VdbReadError::Malformed { grid: None, offset: 0, what },
    })
}

// c-blosc blosc.h: header flags.
const BLOSC_DOSHUFFLE: u8 = 0x1;
const BLOSC_MEMCPYED: u8 = 0x2;
const BLOSC_DOBITSHUFFLE: u8 = 0x4;
const BLOSC_DONT_SPLIT: u8 = 0x10;
/// blosc.c: blocks split into one stream per byte of the type when the
/// type is at most this wide...
const MAX_SPLITS: usize = 16;
/// ...and the block holds at least this many values.
const MIN_BUFFERSIZE: usize = 128;

pub(super) fn blosc_decode(src: &[u8], expected: usize) -> std::result::Result<Vec<u8>, CodecError> {
    let bad = |s: String| Err(CodecError::Corrupt(s));
    if src.len() < 16 {
        return bad(format!("a blosc block of {} bytes, shorter than its 16-byte header", src.len()));
    }
    let le = |at: usize| u32::from_le_bytes([src[at], src[at + 1], src[at + 2], src[at + 3]]) as usize;
    // blosc.c blosc_run_decompression_with_context: the 16-byte header.
    let (version, versionlz, flags, typesize) = (src[0], src[1], src[2], src[3] as usize);
    let (nbytes, blocksize, ctbytes) = (le(4), le(8), le(12));
    if nbytes != expected {
        return bad(format!("a blosc block holds {nbytes} bytes where {expected} were expected"));
    }
    if nbytes == 0 {
        return Ok(Vec::new());
    }
    if version != 2 {
        return Err(CodecError::Unsupported(format!("blosc format version {version} (only blosc 1's format 2 is read)")));
    }
    if flags & 0x08 != 0 {
        return Err(CodecError::Unsupported(format!("blosc header flags {flags:#x} (from a newer blosc)")));
    }
    if blocksize == 0 || blocksize > nbytes || typesize == 0 {
        return bad(format!("a blosc block of {nbytes} bytes in blocks of {blocksize}, type size {typesize}"));
    }
    if ctbytes > src.len() || ctbytes < 16 {
        return bad(format!("a blosc block of {ctbytes} bytes stored in {}", src.len()));
    }
    let src = &src[..ctbytes];
    if flags & BLOSC_MEMCPYED != 0 {
        if nbytes + 16 != ctbytes {
            return bad(format!("a copied blosc block of {nbytes} bytes in {ctbytes}"));
        }
        return Ok(src[16..].to_vec());
    }
    let codec = flags >> 5;
    let decode: fn(&[u8], &mut [u8]) -> Option<usize> = match codec {
        0 => blosclz_decode,
        1 => lz4_decode,
        3 => zlib_into,
        2 => return Err(CodecError::Unsupported("unsupported blosc compressor snappy".into())),
        4 => return Err(CodecError::Unsupported("unsupported blosc compressor zstd".into())),
        c => return Err(CodecError::Unsupported(format!("unsupported blosc compressor (code {c})"))),
    };
    // Each compressor's format version is 1 (blosc.h *_VERSION_FORMAT).
    if versionlz != 1 {
        return Err(CodecError::Unsupported(format!("blosc compressor format version {versionlz}")));
    }
    if flags & BLOSC_DOBITSHUFFLE != 0 && blocksize >= typesize {
        return Err(CodecError::Unsupported("blosc bit shuffle".into()));
    }
    let nblocks = nbytes.div_ceil(blocksize);
    if 16 + 4 * nblocks > ctbytes {
        return bad(format!("a blosc block of {nblocks} blocks has no room for their starts"));
    }
    let mut out = vec![0u8; nbytes];
    let mut tmp = vec![0u8; blocksize];
    for j in 0..nblocks {
        // blosc.c blosc_d.
        let leftover = j == nblocks - 1 && nbytes % blocksize != 0;
        let bsize = if leftover { nbytes % blocksize } else { blocksize };
        let split = flags & BLOSC_DONT_SPLIT == 0 && typesize <= MAX_SPLITS && bsize / typesize >= MIN_BUFFERSIZE && !leftover;
        let nsplits = if split { typesize } else { 1 };
        let neblock = bsize / nsplits;
        let mut at = le(16 + 4 * j);
        let mut done = 0;
        for _ in 0..nsplits {
            if at + 4 > ctbytes {
                return bad(format!("blosc block {j} starts past the end"));
            }
            let cbytes = le(at);
            at += 4;
            if cbytes > ctbytes - at {
                return bad(format!("blosc block {j} runs past the end"));
            }
            let s = &src[at..at + cbytes];
            let dst = &mut tmp[done..done + neblock];
            if cbytes == neblock {
                dst.copy_from_slice(s);
            } else if decode(s, dst) != Some(neblock) {
                return bad(format!("blosc block {j} does not decompress to its {neblock} bytes"));
            }
            at += cbytes;
            done += neblock;
        }
        if done != bsize {
            return bad(format!("blosc block {j} holds {done} bytes, not {bsize}"));
        }
        let dest = &mut out[j * blocksize..j * blocksize + bsize];
        if flags & BLOSC_DOSHUFFLE != 0 && typesize > 1 {
            // shuffle.c unshuffle_generic: byte k of value i was at
            // k·(bsize / typesize) + i; the tail of bsize % typesize bytes
            // was copied as is.
            let n = bsize / typesize;
            for i in 0..n {
                for k in 0..typesize {
                    dest[i * typesize + k] = tmp[k * n + i];
                }
            }
            dest[n * typesize..].copy_from_slice(&tmp[n * typesize..bsize]);
        } else {
            dest.copy_from_slice(&tmp[..bsize]);
        }
    }
    Ok(out)
}

/// zlib into `dst` (blosc.c zlib_wrap_decompress: uncompress()).
fn zlib_into(src: &[u8], dst: &mut [u8]) -> Option<usize> {
    zlib_decode(src, dst.len()).ok().map(|v| {
        dst.copy_from_slice(&v);
        v.len()
    })
}

/// An LZ4 block (LZ4_decompress_safe): sequences of a token (literal length
/// in the high nibble, match length − 4 in the low; 15 continues in bytes
/// that add up while they are 255), the literals, a u16 offset back; the
/// last sequence is literals alone. Returns the bytes written, or None.
fn lz4_decode(src: &[u8], dst: &mut [u8]) -> Option<usize> {
    let (mut ip, mut op) = (0usize, 0usize);
    let length = |ip: &mut usize, mut n: usize| -> Option<usize> {
        if n == 15 {
            loop {
                let b = *src.get(*ip)?;
                *ip += 1;
                n = n.checked_add(usize::from(b))?;
                if b != 255 {
                    break;
                }
            }
        }
        Some(n)
    };
    loop {
        let token = *src.get(ip)?;
        ip += 1;
        let lit = length(&mut ip, usize::from(token >> 4))?;
        if lit > src.len() - ip || lit > dst.len() - op {
            return None;
        }
        dst[op..op + lit].copy_from_slice(&src[ip..ip + lit]);
        ip += lit;
        op += lit;
        if ip == src.len() {
            return Some(op);
        }
        if ip + 2 > src.len() {
            return None;
        }
        let offset = usize::from(u16::from_le_bytes([src[ip], src[ip + 1]]));
        ip += 2;
        if offset == 0 || offset > op {
            return None;
        }
        let len = length(&mut ip, usize::from(token & 15))?.checked_add(4)?;
        if len > dst.len() - op {
            return None;
        }
        // Byte by byte: the match may overlap what it writes.
        for k in 0..len {
            dst[op + k] = dst[op + k - offset];
        }
        op += len;
    }
}

/// blosclz.c blosclz_decompress: the first byte's low 5 bits are a literal
/// run; then a control byte below 32 is a literal run of ctrl + 1 bytes,
/// and above is a match of length (ctrl >> 5) + 2 (7 continues in bytes
/// while 255) at distance ((ctrl & 31) << 8) + next byte + 1, where 31 and
/// 255 mean a 16-bit distance follows (plus 8191).
fn blosclz_decode(src: &[u8], dst: &mut [u8]) -> Option<usize> {
    const MAX_DISTANCE: usize = 8191;
    if src.is_empty() {
        return Some(0);
    }
    let (mut ip, mut op) = (1usize, 0usize);
    let mut ctrl = usize::from(src[0] & 31);
    loop {
        if ctrl >= 32 {
            let mut len = (ctrl >> 5) - 1;
            let mut ofs = (ctrl & 31) << 8;
            if len == 6 {
                loop {
                    if ip + 1 >= src.len() {
                        return None;
                    }
                    let code = src[ip];
                    ip += 1;
                    len += usize::from(code);
                    if code != 255 {
                        break;
                    }
                }
            } else if ip + 1 >= src.len() {
                return None;
            }
            let code = usize::from(src[ip]);
            ip += 1;
            len += 3;
            // The distance back from op to the match's first byte.
            let mut dist = ofs + code + 1;
            if code == 255 && ofs == 31 << 8 {
                if ip + 1 >= src.len() {
                    return None;
                }
                ofs = (usize::from(src[ip]) << 8) + usize::from(src[ip + 1]);
                ip += 2;
                dist = ofs + MAX_DISTANCE + 1;
            }
            if len > dst.len() - op || dist > op {
                return None;
            }
            // As blosclz: a stream that ends after a match's header ends
            // there, without the match.
            if ip >= src.len() {
                break;
            }
            ctrl = usize::from(src[ip]);
            ip += 1;
            for k in 0..len {
                dst[op + k] = dst[op + k - dist];
            }
            op += len;
        } else {
            let run = ctrl + 1;
            if run > dst.len() - op || run > src.len() - ip {
                return None;
            }
            dst[op..op + run].copy_from_slice(&src[ip..ip + run]);
            op += run;
            ip += run;
            if ip >= src.len() {
                break;
            }
            ctrl = usize::from(src[ip]);
            ip += 1;
        }
    }
    Some(op)
}
