//! Bitwise CRCs, MSB-first, no reflection, no final xor: the device
//! protocols differ only in polynomial and initial value.

/// CRC-8 over `data` with polynomial `poly` and initial value `init`.
pub fn crc8_msb(poly: u8, init: u8, data: &[u8]) -> u8 {
    let mut crc = init;
    for &b in data {
        crc ^= b;
        for _ in 0..8 {
            crc = if crc & 0x80 != 0 {
                (crc << 1) ^ poly
            } else {
                crc << 1
            };
        }
    }
    crc
}

/// CRC-16 over `data` with polynomial `poly` and initial value `init`.
pub fn crc16_msb(poly: u16, init: u16, data: &[u8]) -> u16 {
    let mut crc = init;
    for &b in data {
        crc ^= (b as u16) << 8;
        for _ in 0..8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ poly
            } else {
                crc << 1
            };
        }
    }
    crc
}
