//! The WSG frame checksum (manual, Anhang D).
//!
//! The manual's table is the MSB-first table of the CRC-CCITT polynomial 0x1021
//! (`CRC_TABLE[1] == 0x1021`), but its update step is the LSB-first (reflected) form
//! `crc = TABLE[(crc ^ byte) & 0xFF] ^ (crc >> 8)`, with init 0xFFFF and no final XOR. That hybrid
//! is not a catalogue CRC, so no `crc`-crate `Algorithm` computes it: the crate keeps the manual's
//! table (generated here by a `const fn`; every entry is pinned by a test against the manual's
//! printed values and against CRC-16/XMODEM of the single byte) and its update rule.
//!
//! Running the computation over a whole frame *including* its two checksum bytes (little endian)
//! yields 0 (manual 1.2.1), but because of the hybrid, so do about three other checksum values per
//! frame: a received frame is verified by comparing its checksum field with the checksum of the
//! bytes before it ([`super::frame::decode`]).

/// Initial value of the checksum register (Anhang D: "The start value ... should be set to
/// 0xFFFF").
pub const INIT: u16 = 0xFFFF;

/// The manual's 256-entry table (Anhang D `CRC_TABLE`): entry `i` is the MSB-first CRC-CCITT
/// (polynomial 0x1021) of the byte `i`.
pub const TABLE: [u16; 256] = make_table();

const fn make_table() -> [u16; 256] {
    let mut table = [0u16; 256];
    let mut i = 0;
    while i < 256 {
        let mut crc = (i as u16) << 8;
        let mut bit = 0;
        while bit < 8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ 0x1021
            } else {
                crc << 1
            };
            bit += 1;
        }
        table[i] = crc;
        i += 1;
    }
    table
}

/// Continues a checksum computation over `data`, starting from the register value `crc`
/// (Anhang D `checksum_update_crc16`). Start with [`INIT`].
#[inline]
pub fn update(mut crc: u16, data: &[u8]) -> u16 {
    for &byte in data {
        crc = TABLE[usize::from((crc ^ u16::from(byte)) as u8)] ^ (crc >> 8);
    }
    crc
}

/// The checksum of `data` (init 0xFFFF, no final XOR), as appended little endian to a frame.
///
/// Computed eight bytes per step ([`update_slice8`], equal to the manual's [`update`] on every
/// input): every frame sent and received is checksummed, and the byte-wise loop was most of the
/// cost of decoding a short frame (`benches/wsg.rs`, BENCHMARKS.md).
#[inline]
pub fn checksum(data: &[u8]) -> u16 {
    update_slice8(INIT, data)
}

/// Tables for the slicing-by-8 variant: `SLICE8[k][i]` is the register contribution of byte `i`
/// followed by `k` zero bytes.
const SLICE8: [[u16; 256]; 8] = make_slice8();

const fn make_slice8() -> [[u16; 256]; 8] {
    let mut t = [[0u16; 256]; 8];
    t[0] = TABLE;
    let mut k = 1;
    while k < 8 {
        let mut i = 0;
        while i < 256 {
            let prev = t[k - 1][i];
            t[k][i] = TABLE[(prev & 0xFF) as usize] ^ (prev >> 8);
            i += 1;
        }
        k += 1;
    }
    t
}

/// The same checksum as [`update`], eight bytes per step (slicing-by-8).
///
/// Equal to [`update`] for every input (pinned by a property test); faster on long payloads
/// (see `benches/wsg.rs`). The update rule is linear in the register, so eight table lookups
/// combine the contributions of the register and of eight bytes at once.
pub fn update_slice8(mut crc: u16, data: &[u8]) -> u16 {
    let mut chunks = data.chunks_exact(8);
    for c in &mut chunks {
        let b0 = c[0] ^ (crc as u8);
        let b1 = c[1] ^ ((crc >> 8) as u8);
        crc = SLICE8[7][usize::from(b0)]
            ^ SLICE8[6][usize::from(b1)]
            ^ SLICE8[5][usize::from(c[2])]
            ^ SLICE8[4][usize::from(c[3])]
            ^ SLICE8[3][usize::from(c[4])]
            ^ SLICE8[2][usize::from(c[5])]
            ^ SLICE8[1][usize::from(c[6])]
            ^ SLICE8[0][usize::from(c[7])];
    }
    update(crc, chunks.remainder())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// The manual's table as printed in Anhang D (the OCR's first entry `0000h` is 0x0000).
    #[rustfmt::skip]
    const MANUAL_TABLE: [u16; 256] = [
        0x0000, 0x1021, 0x2042, 0x3063, 0x4084, 0x50a5, 0x60c6, 0x70e7,
        0x8108, 0x9129, 0xa14a, 0xb16b, 0xc18c, 0xd1ad, 0xe1ce, 0xf1ef,
        0x1231, 0x0210, 0x3273, 0x2252, 0x52b5, 0x4294, 0x72f7, 0x62d6,
        0x9339, 0x8318, 0xb37b, 0xa35a, 0xd3bd, 0xc39c, 0xf3ff, 0xe3de,
        0x2462, 0x3443, 0x0420, 0x1401, 0x64e6, 0x74c7, 0x44a4, 0x5485,
        0xa56a, 0xb54b, 0x8528, 0x9509, 0xe5ee, 0xf5cf, 0xc5ac, 0xd58d,
        0x3653, 0x2672, 0x1611, 0x0630, 0x76d7, 0x66f6, 0x5695, 0x46b4,
        0xb75b, 0xa77a, 0x9719, 0x8738, 0xf7df, 0xe7fe, 0xd79d, 0xc7bc,
        0x48c4, 0x58e5, 0x6886, 0x78a7, 0x0840, 0x1861, 0x2802, 0x3823,
        0xc9cc, 0xd9ed, 0xe98e, 0xf9af, 0x8948, 0x9969, 0xa90a, 0xb92b,
        0x5af5, 0x4ad4, 0x7ab7, 0x6a96, 0x1a71, 0x0a50, 0x3a33, 0x2a12,
        0xdbfd, 0xcbdc, 0xfbbf, 0xeb9e, 0x9b79, 0x8b58, 0xbb3b, 0xab1a,
        0x6ca6, 0x7c87, 0x4ce4, 0x5cc5, 0x2c22, 0x3c03, 0x0c60, 0x1c41,
        0xedae, 0xfd8f, 0xcdec, 0xddcd, 0xad2a, 0xbd0b, 0x8d68, 0x9d49,
        0x7e97, 0x6eb6, 0x5ed5, 0x4ef4, 0x3e13, 0x2e32, 0x1e51, 0x0e70,
        0xff9f, 0xefbe, 0xdfdd, 0xcffc, 0xbf1b, 0xaf3a, 0x9f59, 0x8f78,
        0x9188, 0x81a9, 0xb1ca, 0xa1eb, 0xd10c, 0xc12d, 0xf14e, 0xe16f,
        0x1080, 0x00a1, 0x30c2, 0x20e3, 0x5004, 0x4025, 0x7046, 0x6067,
        0x83b9, 0x9398, 0xa3fb, 0xb3da, 0xc33d, 0xd31c, 0xe37f, 0xf35e,
        0x02b1, 0x1290, 0x22f3, 0x32d2, 0x4235, 0x5214, 0x6277, 0x7256,
        0xb5ea, 0xa5cb, 0x95a8, 0x8589, 0xf56e, 0xe54f, 0xd52c, 0xc50d,
        0x34e2, 0x24c3, 0x14a0, 0x0481, 0x7466, 0x6447, 0x5424, 0x4405,
        0xa7db, 0xb7fa, 0x8799, 0x97b8, 0xe75f, 0xf77e, 0xc71d, 0xd73c,
        0x26d3, 0x36f2, 0x0691, 0x16b0, 0x6657, 0x7676, 0x4615, 0x5634,
        0xd94c, 0xc96d, 0xf90e, 0xe92f, 0x99c8, 0x89e9, 0xb98a, 0xa9ab,
        0x5844, 0x4865, 0x7806, 0x6827, 0x18c0, 0x08e1, 0x3882, 0x28a3,
        0xcb7d, 0xdb5c, 0xeb3f, 0xfb1e, 0x8bf9, 0x9bd8, 0xabbb, 0xbb9a,
        0x4a75, 0x5a54, 0x6a37, 0x7a16, 0x0af1, 0x1ad0, 0x2ab3, 0x3a92,
        0xfd2e, 0xed0f, 0xdd6c, 0xcd4d, 0xbdaa, 0xad8b, 0x9de8, 0x8dc9,
        0x7c26, 0x6c07, 0x5c64, 0x4c45, 0x3ca2, 0x2c83, 0x1ce0, 0x0cc1,
        0xef1f, 0xff3e, 0xcf5d, 0xdf7c, 0xaf9b, 0xbfba, 0x8fd9, 0x9ff8,
        0x6e17, 0x7e36, 0x4e55, 0x5e74, 0x2e93, 0x3eb2, 0x0ed1, 0x1ef0,
    ];

    #[test]
    fn generated_table_is_the_manuals() {
        assert_eq!(TABLE, MANUAL_TABLE);
    }

    #[test]
    fn every_table_entry_is_xmodem_of_its_index() {
        let xmodem = crc::Crc::<u16>::new(&crc::CRC_16_XMODEM);
        for i in 0..=255u8 {
            assert_eq!(
                TABLE[usize::from(i)],
                xmodem.checksum(&[i]),
                "entry {i:#04x}"
            );
        }
    }

    #[test]
    fn check_value() {
        assert_eq!(checksum(b"123456789"), 0x6EB4);
    }

    #[test]
    fn no_catalogue_algorithm_matches() {
        // Why the library does not depend on `crc`: neither XMODEM nor its reflected sibling
        // (KERMIT with init 0xFFFF = CRC-16/MCRF4XX) nor CCITT-FALSE give the manual's value.
        for alg in [
            &crc::CRC_16_XMODEM,
            &crc::CRC_16_IBM_3740,
            &crc::CRC_16_MCRF4XX,
            &crc::CRC_16_KERMIT,
        ] {
            assert_ne!(crc::Crc::<u16>::new(alg).checksum(b"123456789"), 0x6EB4);
        }
    }

    /// Every vector of PROTOCOLS.md section 1: the last two bytes are the checksum (LE) of the
    /// rest, and the checksum over the whole frame is 0.
    pub(crate) const VECTORS: &[&[u8]] = &[
        &[0xAA, 0xAA, 0xAA, 0x01, 0x00, 0x00, 0xE8, 0x10],
        &[0xAA, 0xAA, 0xAA, 0x01, 0x02, 0x00, 0x12, 0x34, 0x6D, 0x66],
        &[0xAA, 0xAA, 0xAA, 0x20, 0x02, 0x00, 0x00, 0x00, 0xB3, 0xFD],
        &[0xAA, 0xAA, 0xAA, 0x90, 0x02, 0x00, 0x0E, 0x00, 0xFD, 0x02],
        &[
            0xAA, 0xAA, 0xAA, 0x30, 0x06, 0x00, 0x00, 0x00, 0x00, 0x00, 0x16, 0x43, 0xDC, 0xCB,
        ],
        &[0xAA, 0xAA, 0xAA, 0x21, 0x02, 0x00, 0x1A, 0x00, 0x67, 0xCB],
        &[0xAA, 0xAA, 0xAA, 0x21, 0x02, 0x00, 0x00, 0x00, 0x28, 0x04],
        &[0xAA, 0xAA, 0xAA, 0x20, 0x01, 0x00, 0x00, 0x8F, 0x83],
        &[
            0xAA, 0xAA, 0xAA, 0x25, 0x08, 0x00, 0x00, 0x00, 0xA0, 0x41, 0x00, 0x00, 0x48, 0x42,
            0xAA, 0x1E,
        ],
        &[
            0xAA, 0xAA, 0xAA, 0x21, 0x09, 0x00, 0x02, 0x00, 0x00, 0x0E, 0x42, 0x00, 0x00, 0x20,
            0x42, 0xBA, 0x3C,
        ],
        &[
            0xAA, 0xAA, 0xAA, 0x24, 0x03, 0x00, 0x61, 0x63, 0x6B, 0xDC, 0xB9,
        ],
        &[
            0xAA, 0xAA, 0xAA, 0x43, 0x03, 0x00, 0x03, 0x32, 0x00, 0x58, 0xAD,
        ],
        &[
            0xAA, 0xAA, 0xAA, 0x43, 0x06, 0x00, 0x00, 0x00, 0x00, 0x00, 0x48, 0x41, 0x01, 0xCF,
        ],
        &[
            0xAA, 0xAA, 0xAA, 0x40, 0x06, 0x00, 0x00, 0x00, 0x03, 0x00, 0x00, 0x00, 0xF0, 0xB5,
        ],
        &[
            0xAA, 0xAA, 0xAA, 0x46, 0x04, 0x00, 0x00, 0x00, 0xEA, 0x00, 0xC6, 0x16,
        ],
        &[0xAA, 0xAA, 0xAA, 0x07, 0x00, 0x00, 0x35, 0x4C],
    ];

    #[test]
    fn protocol_vectors() {
        for v in VECTORS {
            let (body, crc) = v.split_at(v.len() - 2);
            assert_eq!(checksum(body).to_le_bytes(), crc, "vector {v:02X?}");
            assert_eq!(checksum(v), 0, "whole frame of {v:02X?}");
            assert_eq!(update(INIT, v), 0, "manual's byte-wise rule over {v:02X?}");
            assert_eq!(update_slice8(INIT, v), 0);
        }
    }

    proptest::proptest! {
        #[test]
        fn slice8_equals_bytewise(data: Vec<u8>, init: u16) {
            proptest::prop_assert_eq!(update_slice8(init, &data), update(init, &data));
        }
    }
}
