/*
 * opennav encoder bridge: the wire protocol between the Arduino Mega 2560
 * encoder board and the host (src/sensors/encoders.rs mirrors it).
 *
 * Every message is   COBS( type | payload | crc16 ) 0x00
 *   - COBS: consistent overhead byte stuffing, so 0x00 only ends a frame and
 *     the stream resynchronises at the next 0x00 after any corruption;
 *   - crc16: CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no
 *     final xor) over type and payload, sent little-endian;
 *   - all integers little-endian.
 *
 * type 0x01 COUNTS, every 10 ms (100 Hz), payload 20 bytes:
 *   u16 seq              increments by 1 per COUNTS frame, wraps
 *   u32 mcu_time_us      microseconds since boot at the count snapshot, wraps
 *   i32 left_count       x4 quadrature count, left wheel
 *   i32 right_count      x4 quadrature count, right wheel
 *   u16 left_illegal     illegal transitions seen (both channels changed)
 *   u16 right_illegal
 *   u8  flags            bit 0: UART transmit overrun (a frame was dropped)
 *   u8  reserved         0
 *
 * type 0x02 HELLO, once at boot, payload 8 bytes:
 *   u8  protocol_version (1)
 *   u8  firmware_major, u8 firmware_minor, u8 firmware_patch
 *   u16 frame_rate_hz    (100)
 *   u16 reserved         0
 */
#ifndef OPENNAV_ENCODER_PROTOCOL_H
#define OPENNAV_ENCODER_PROTOCOL_H

#include <stdint.h>

#define ENC_PROTOCOL_VERSION 1
#define ENC_TYPE_COUNTS 0x01
#define ENC_TYPE_HELLO 0x02
#define ENC_COUNTS_PAYLOAD 20
#define ENC_HELLO_PAYLOAD 8
#define ENC_FRAME_RATE_HZ 100
#define ENC_BAUD 115200UL

/* largest raw message: type + payload + crc */
#define ENC_MAX_RAW (1 + ENC_COUNTS_PAYLOAD + 2)
/* COBS adds at most one byte per 254, plus the leading code byte */
#define ENC_MAX_ENCODED (ENC_MAX_RAW + 2)

static inline uint16_t enc_crc16(const uint8_t *data, uint8_t len)
{
    uint16_t crc = 0xFFFF;
    for (uint8_t i = 0; i < len; i++) {
        crc ^= (uint16_t)data[i] << 8;
        for (uint8_t b = 0; b < 8; b++)
            crc = (crc & 0x8000) ? (uint16_t)((crc << 1) ^ 0x1021) : (uint16_t)(crc << 1);
    }
    return crc;
}

/* COBS-encodes len bytes of src into dst (no trailing zero); returns the
 * encoded length. dst must hold len + len/254 + 1 bytes. */
static inline uint8_t enc_cobs_encode(const uint8_t *src, uint8_t len, uint8_t *dst)
{
    uint8_t code_at = 0, out = 1, code = 1;
    for (uint8_t i = 0; i < len; i++) {
        if (src[i] == 0) {
            dst[code_at] = code;
            code_at = out++;
            code = 1;
        } else {
            dst[out++] = src[i];
            if (++code == 0xFF) {
                dst[code_at] = code;
                code_at = out++;
                code = 1;
            }
        }
    }
    dst[code_at] = code;
    return out;
}

#endif
