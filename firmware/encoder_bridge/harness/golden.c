/* Prints the encoded bytes of two fixed messages, built with the firmware's
 * own protocol.h on the host: the golden vectors the Rust codec must match.
 *   COUNTS seq 1, t 10000 us, left -5, right 300, illegal 1 / 2, no overrun
 *   HELLO  protocol 1, firmware 1.0.0, 100 Hz */
#include <stdio.h>
#include "../protocol.h"

static void put16(uint8_t *p, uint16_t v) { p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); }
static void put32(uint8_t *p, uint32_t v) { for (int i = 0; i < 4; i++) p[i] = (uint8_t)(v >> (8 * i)); }

static void emit(const uint8_t *raw, uint8_t len)
{
    uint8_t buf[ENC_MAX_RAW], enc[ENC_MAX_ENCODED];
    for (uint8_t i = 0; i < len; i++) buf[i] = raw[i];
    uint16_t crc = enc_crc16(buf, len);
    buf[len] = (uint8_t)crc;
    buf[len + 1] = (uint8_t)(crc >> 8);
    uint8_t n = enc_cobs_encode(buf, (uint8_t)(len + 2), enc);
    for (uint8_t i = 0; i < n; i++) printf("%02x", enc[i]);
    printf("00\n");
}

int main(void)
{
    uint8_t m[1 + ENC_COUNTS_PAYLOAD] = {ENC_TYPE_COUNTS};
    put16(&m[1], 1);
    put32(&m[3], 10000);
    put32(&m[7], (uint32_t)-5);
    put32(&m[11], 300);
    put16(&m[15], 1);
    put16(&m[17], 2);
    m[19] = 0;
    m[20] = 0;
    emit(m, sizeof m);
    uint8_t h[1 + ENC_HELLO_PAYLOAD] = {ENC_TYPE_HELLO, ENC_PROTOCOL_VERSION, 1, 0, 0, 0, 0, 0, 0};
    put16(&h[5], ENC_FRAME_RATE_HZ);
    emit(h, sizeof h);
    return 0;
}
