/*
 * simavr harness for the encoder bridge firmware: runs the real firmware ELF
 * on a simulated ATmega2560, drives both encoders' pins with quadrature
 * waveforms (speed profiles, direction changes, glitches), and exposes
 * UART0 on a pseudo-terminal published at LINK (the host driver opens it).
 *
 *   harness FIRMWARE.elf LINK SIM_SECONDS [LINGER_MS]
 *
 * When the simulated time is over (plus 50 ms of idle so the last frames
 * report the final counts), it prints the truth as one JSON line on stdout:
 *   {"left": N, "right": N, "left_illegal": N, "right_illegal": N,
 *    "sim_seconds": S, "frames_expected": N}
 * then keeps the pty open LINGER_MS (default 3000) for the reader.
 */
#define _XOPEN_SOURCE 600
#define _DEFAULT_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <unistd.h>

#include <sim_avr.h>
#include <sim_elf.h>
#include <sim_time.h>
#include <avr_ioport.h>
#include <avr_uart.h>

static avr_t *avr;
static int master_fd = -1;

typedef struct wheel {
    const char *name;
    avr_irq_t *a, *b;
    int phase;       /* index in the forward sequence 00,10,11,01 */
    long count;      /* legitimate steps, signed */
    long illegal;    /* glitches injected */
    int profile;     /* 0: left, 1: right */
} wheel_t;

static wheel_t left, right;
static double end_seconds;

static const int SEQ_A[4] = {0, 1, 1, 0};
static const int SEQ_B[4] = {0, 0, 1, 1};

static double now_s(void) { return (double)avr->cycle / (double)avr->frequency; }

static void set_pins(wheel_t *w)
{
    avr_raise_irq(w->a, SEQ_A[w->phase]);
    avr_raise_irq(w->b, SEQ_B[w->phase]);
}

/* steps per second (signed) at time t: the left wheel accelerates, cruises,
 * reverses; the right one turns steadily, stops, turns back */
static double rate(const wheel_t *w, double t)
{
    if (t >= end_seconds)
        return 0.0;
    if (w->profile == 0) {
        if (t < 2.0) return 500.0 + 1000.0 * t;      /* ramp to 2500 steps/s */
        if (t < 5.0) return 2500.0;
        if (t < 6.0) return 2500.0 - 4000.0 * (t - 5.0); /* through zero */
        return -1500.0 - 300.0 * sin(t);
    }
    if (t < 4.0) return 1800.0;
    if (t < 4.5) return 0.0;
    return -1200.0;
}

static avr_cycle_count_t tick(avr_t *a, avr_cycle_count_t when, void *param)
{
    wheel_t *w = param;
    double t = (double)when / (double)a->frequency;
    double r = rate(w, t);
    /* a glitch every 1.5 s on the left wheel, every 2.5 s on the right:
     * both channels flip at once (an illegal transition) */
    double every = w->profile == 0 ? 1.5 : 2.5;
    static double next_glitch[2] = {1.5, 2.5};
    if (t < end_seconds && t >= next_glitch[w->profile]) {
        next_glitch[w->profile] += every;
        w->phase = (w->phase + 2) & 3;
        w->illegal++;
        set_pins(w);
        return when + a->frequency / 20000; /* 50 us later, carry on */
    }
    if (fabs(r) < 1.0)
        return when + a->frequency / 1000; /* idle: look again in 1 ms */
    int dir = r > 0 ? 1 : -1;
    w->phase = (w->phase + (dir > 0 ? 1 : 3)) & 3;
    w->count += dir;
    set_pins(w);
    avr_cycle_count_t period = (avr_cycle_count_t)((double)a->frequency / fabs(r));
    return when + (period ? period : 1);
}

static void uart_out(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    (void)param;
    uint8_t b = (uint8_t)value;
    while (write(master_fd, &b, 1) < 0 && (errno == EINTR || errno == EAGAIN))
        usleep(100);
}

int main(int argc, char **argv)
{
    if (argc < 4) {
        fprintf(stderr, "usage: %s FIRMWARE.elf LINK SIM_SECONDS [LINGER_MS]\n", argv[0]);
        return 2;
    }
    const char *elf = argv[1], *link = argv[2];
    end_seconds = atof(argv[3]);
    int linger_ms = argc > 4 ? atoi(argv[4]) : 3000;

    elf_firmware_t fw;
    memset(&fw, 0, sizeof fw);
    if (elf_read_firmware(elf, &fw) != 0) {
        fprintf(stderr, "harness: cannot read %s\n", elf);
        return 1;
    }
    if (!fw.mmcu[0]) {
        fprintf(stderr, "harness: %s has no simavr MCU section\n", elf);
        return 1;
    }
    avr = avr_make_mcu_by_name(fw.mmcu);
    if (!avr) {
        fprintf(stderr, "harness: unknown MCU %s\n", fw.mmcu);
        return 1;
    }
    avr_init(avr);
    avr->frequency = fw.frequency;
    avr->log = 1;
    avr_load_firmware(avr, &fw);

    /* the pty: raw, its slave kept open, published at LINK */
    master_fd = posix_openpt(O_RDWR | O_NOCTTY);
    if (master_fd < 0 || grantpt(master_fd) || unlockpt(master_fd)) {
        perror("harness: pty");
        return 1;
    }
    const char *slave_name = ptsname(master_fd);
    int slave_fd = open(slave_name, O_RDWR | O_NOCTTY);
    struct termios tio;
    tcgetattr(slave_fd, &tio);
    cfmakeraw(&tio);
    tcsetattr(slave_fd, TCSANOW, &tio);
    unlink(link);
    if (symlink(slave_name, link) != 0) {
        perror("harness: symlink");
        return 1;
    }

    /* UART0 out → pty; no flow-control stall in the model */
    uint32_t flags = 0;
    avr_ioctl(avr, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
    flags &= ~AVR_UART_FLAG_STDIO;
    avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT), uart_out, NULL);

    /* encoder pins: left A PE4, B PE5; right A PD3, B PD2 */
    /* both wheels start in state 11, the level the firmware's pull-ups give
     * an idle open-collector encoder */
    left = (wheel_t){"left", avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('E'), 4),
                     avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('E'), 5), 2, 0, 0, 0};
    right = (wheel_t){"right", avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('D'), 3),
                      avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('D'), 2), 2, 0, 0, 1};
    set_pins(&left);
    set_pins(&right);
    /* start turning after 20 ms, once the firmware has set up */
    avr_cycle_timer_register_usec(avr, 20000, tick, &left);
    avr_cycle_timer_register_usec(avr, 20000, tick, &right);

    double stop = end_seconds + 0.05;
    int state = cpu_Running;
    while (now_s() < stop) {
        state = avr_run(avr);
        if (state == cpu_Done || state == cpu_Crashed) {
            fprintf(stderr, "harness: firmware stopped (state %d) at %.3f s\n", state, now_s());
            return 1;
        }
    }
    printf("{\"left\": %ld, \"right\": %ld, \"left_illegal\": %ld, \"right_illegal\": %ld, "
           "\"sim_seconds\": %.6f, \"frames_expected\": %ld}\n",
           left.count, right.count, left.illegal, right.illegal, now_s(), (long)(now_s() * 100.0));
    fflush(stdout);
    usleep((useconds_t)linger_ms * 1000);
    unlink(link);
    close(slave_fd);
    close(master_fd);
    return 0;
}
