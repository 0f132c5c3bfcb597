/*
 * opennav encoder bridge firmware: Arduino Mega 2560 (ATmega2560, 16 MHz).
 *
 * Two quadrature encoders decoded x4, both channels of each on external
 * interrupt pins (any edge):
 *   left  A = Arduino pin 2  (PE4, INT4)   left  B = pin 3  (PE5, INT5)
 *   right A = Arduino pin 18 (PD3, INT3)   right B = pin 19 (PD2, INT2)
 * 32-bit signed counts, illegal transitions (both channels changed at once)
 * counted. Every 10 ms (Timer1) the counts and the microsecond clock
 * (Timer3) are snapshotted together and sent as a COUNTS frame (see
 * protocol.h) on UART0 at 115200 8N1; a HELLO frame goes out at boot.
 * Plain avr-gcc + avr-libc, no Arduino core.
 */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <stdint.h>

#include "protocol.h"

#ifdef OPENNAV_SIMAVR
#include <avr/avr_mcu_section.h>
AVR_MCU(F_CPU, "atmega2560");
#endif

#define FW_MAJOR 1
#define FW_MINOR 0
#define FW_PATCH 0

/* quadrature state (A << 1 | B): +1 along 00 -> 10 -> 11 -> 01 -> 00,
 * -1 the other way, 0 no change, 2 = illegal (both changed) */
static const int8_t QTABLE[16] = {
    /* prev 00 */ 0, -1, +1, 2,
    /* prev 01 */ +1, 0, 2, -1,
    /* prev 10 */ -1, 2, 0, +1,
    /* prev 11 */ 2, +1, -1, 0,
};

static volatile int32_t left_count, right_count;
static volatile uint16_t left_illegal, right_illegal;
static volatile uint8_t left_state, right_state;
static volatile uint16_t t3_overflows;

/* snapshot taken in the 100 Hz tick, sent by the main loop */
static volatile uint8_t snap_ready, snap_overrun;
static int32_t snap_left, snap_right;
static uint16_t snap_left_illegal, snap_right_illegal;
static uint32_t snap_time_us;

static inline uint8_t read_left(void) { return (uint8_t)((((PINE >> PE4) & 1) << 1) | ((PINE >> PE5) & 1)); }
static inline uint8_t read_right(void) { return (uint8_t)((((PIND >> PD3) & 1) << 1) | ((PIND >> PD2) & 1)); }

static inline void step(volatile uint8_t *state, uint8_t now, volatile int32_t *count, volatile uint16_t *illegal)
{
    int8_t d = QTABLE[(*state << 2) | now];
    if (d == 2) {
        if (*illegal != 0xFFFF)
            (*illegal)++;
    } else {
        *count += d;
    }
    *state = now;
}

ISR(INT4_vect) { step(&left_state, read_left(), &left_count, &left_illegal); }
ISR(INT5_vect, ISR_ALIASOF(INT4_vect));
ISR(INT3_vect) { step(&right_state, read_right(), &right_count, &right_illegal); }
ISR(INT2_vect, ISR_ALIASOF(INT3_vect));

ISR(TIMER3_OVF_vect) { t3_overflows++; }

/* microseconds since boot (Timer3 at 2 MHz); call with interrupts off */
static uint32_t micros_locked(void)
{
    uint16_t lo = TCNT3;
    uint16_t hi = t3_overflows;
    if ((TIFR3 & _BV(TOV3)) && lo < 0x8000)
        hi++; /* overflow pending, not yet counted */
    return (((uint32_t)hi << 16) | lo) >> 1;
}

ISR(TIMER1_COMPA_vect)
{
    if (snap_ready)
        snap_overrun = 1; /* the previous frame was not sent yet */
    snap_time_us = micros_locked();
    snap_left = left_count;
    snap_right = right_count;
    snap_left_illegal = left_illegal;
    snap_right_illegal = right_illegal;
    snap_ready = 1;
}

static void uart_init(void)
{
    UCSR0A = _BV(U2X0);
    UBRR0 = (uint16_t)(F_CPU / (8UL * ENC_BAUD) - 1);
    UCSR0B = _BV(TXEN0);
    UCSR0C = _BV(UCSZ01) | _BV(UCSZ00); /* 8N1 */
}

static void uart_put(uint8_t b)
{
    while (!(UCSR0A & _BV(UDRE0)))
        ;
    UDR0 = b;
}

static void send_message(const uint8_t *raw, uint8_t len)
{
    uint8_t buf[ENC_MAX_RAW];
    uint8_t enc[ENC_MAX_ENCODED];
    for (uint8_t i = 0; i < len; i++)
        buf[i] = raw[i];
    uint16_t crc = enc_crc16(buf, len);
    buf[len] = (uint8_t)crc;
    buf[len + 1] = (uint8_t)(crc >> 8);
    uint8_t n = enc_cobs_encode(buf, (uint8_t)(len + 2), enc);
    for (uint8_t i = 0; i < n; i++)
        uart_put(enc[i]);
    uart_put(0);
}

static void put16(uint8_t *p, uint16_t v) { p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); }
static void put32(uint8_t *p, uint32_t v) { for (uint8_t i = 0; i < 4; i++) p[i] = (uint8_t)(v >> (8 * i)); }

int main(void)
{
    /* encoder pins: inputs with pull-ups */
    DDRE &= (uint8_t)~(_BV(PE4) | _BV(PE5));
    PORTE |= _BV(PE4) | _BV(PE5);
    DDRD &= (uint8_t)~(_BV(PD2) | _BV(PD3));
    PORTD |= _BV(PD2) | _BV(PD3);
    left_state = read_left();
    right_state = read_right();

    /* any-edge interrupts on INT2..INT5 */
    EICRA = _BV(ISC20) | _BV(ISC30);
    EICRB = _BV(ISC40) | _BV(ISC50);
    EIFR = _BV(INTF2) | _BV(INTF3) | _BV(INTF4) | _BV(INTF5);
    EIMSK = _BV(INT2) | _BV(INT3) | _BV(INT4) | _BV(INT5);

    /* Timer3: free-running at F_CPU/8 = 2 MHz, overflow counted */
    TCCR3A = 0;
    TCCR3B = _BV(CS31);
    TIMSK3 = _BV(TOIE3);

    /* Timer1: CTC at 100 Hz (F_CPU/64 = 250 kHz, 2500 counts) */
    TCCR1A = 0;
    TCCR1B = _BV(WGM12) | _BV(CS11) | _BV(CS10);
    OCR1A = (uint16_t)(F_CPU / 64 / ENC_FRAME_RATE_HZ - 1);
    TIMSK1 = _BV(OCIE1A);

    uart_init();
    sei();

    uint8_t hello[1 + ENC_HELLO_PAYLOAD] = {ENC_TYPE_HELLO, ENC_PROTOCOL_VERSION, FW_MAJOR, FW_MINOR, FW_PATCH, 0, 0, 0, 0};
    put16(&hello[5], ENC_FRAME_RATE_HZ);
    send_message(hello, sizeof hello);

    uint16_t seq = 0;
    for (;;) {
        if (!snap_ready)
            continue;
        uint8_t m[1 + ENC_COUNTS_PAYLOAD];
        cli();
        m[0] = ENC_TYPE_COUNTS;
        put16(&m[1], seq);
        put32(&m[3], snap_time_us);
        put32(&m[7], (uint32_t)snap_left);
        put32(&m[11], (uint32_t)snap_right);
        put16(&m[15], snap_left_illegal);
        put16(&m[17], snap_right_illegal);
        m[19] = snap_overrun ? 1 : 0;
        m[20] = 0;
        snap_overrun = 0;
        snap_ready = 0;
        sei();
        send_message(m, sizeof m);
        seq++;
    }
}
