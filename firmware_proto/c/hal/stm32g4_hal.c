/*
 * Reference board support for the rig firmware core on an STM32G431 (Cortex-M4F, 170 MHz):
 *
 *   time     SysTick at 1 kHz plus its down-counter: microseconds since power-up
 *   CAN      FDCAN1 in classic CAN mode, 500 kbit/s, polled (RX FIFO 0, TX FIFO)
 *   LVDT     ADC1 channel 1 (PA0), conditioned to 0..3.3 V over 0..20 mm
 *   current  ADC1 channel 2 (PA1), a shunt amplifier, 0..3.3 V over -16..+16 A
 *   drive    TIM1 channel 1 complementary PWM into the H-bridge: duty = drive / supply
 *   supply   ADC1 channel 3 (PA2), a 1:11 divider
 *
 * Register-level and polled, with no vendor library: a starting point a rig builder adapts to their board
 * (clock tree, pins, scaling), compiled in CI with arm-none-eabi-gcc. Not run on hardware in this repository:
 * run `edc-bench rig-check` against the built rig before its first valve (docs/rig-check.md).
 */
#include <stdint.h>

#include "rig_firmware.h"

#define REG(address) (*(volatile uint32_t *)(address))

/* -- board constants (adapt these) ------------------------------------------------------------------------ */
#define CPU_HZ 170000000u
#define LVDT_MM_PER_COUNT (20.0 / 4095.0)
#define CURRENT_A_PER_COUNT (32.0 / 4095.0)
#define CURRENT_ZERO_COUNT 2048.0
#define SUPPLY_V_PER_COUNT (3.3 * 11.0 / 4095.0)
#define PWM_PERIOD 8499u /* 20 kHz at 170 MHz */

/* -- peripherals (RM0440) --------------------------------------------------------------------------------- */
#define SYST_CSR 0xE000E010u
#define SYST_RVR 0xE000E014u
#define SYST_CVR 0xE000E018u
#define RCC_BASE 0x40021000u
#define RCC_AHB2ENR REG(RCC_BASE + 0x4Cu)
#define RCC_APB1ENR1 REG(RCC_BASE + 0x58u)
#define RCC_APB2ENR REG(RCC_BASE + 0x60u)
#define ADC1_BASE 0x50000000u
#define ADC1_ISR REG(ADC1_BASE + 0x00u)
#define ADC1_CR REG(ADC1_BASE + 0x08u)
#define ADC1_SQR1 REG(ADC1_BASE + 0x30u)
#define ADC1_DR REG(ADC1_BASE + 0x40u)
#define TIM1_BASE 0x40012C00u
#define TIM1_CR1 REG(TIM1_BASE + 0x00u)
#define TIM1_CCMR1 REG(TIM1_BASE + 0x18u)
#define TIM1_CCER REG(TIM1_BASE + 0x20u)
#define TIM1_ARR REG(TIM1_BASE + 0x2Cu)
#define TIM1_CCR1 REG(TIM1_BASE + 0x34u)
#define TIM1_BDTR REG(TIM1_BASE + 0x44u)
#define TIM1_DIR_GPIO_BSRR REG(0x48000400u + 0x18u) /* PB0: the H-bridge's direction pin */
#define FDCAN1_BASE 0x40006400u
#define FDCAN_CCCR REG(FDCAN1_BASE + 0x18u)
#define FDCAN_NBTP REG(FDCAN1_BASE + 0x1Cu)
#define FDCAN_RXF0S REG(FDCAN1_BASE + 0x90u)
#define FDCAN_RXF0A REG(FDCAN1_BASE + 0x94u)
#define FDCAN_TXFQS REG(FDCAN1_BASE + 0xC4u)
#define FDCAN_TXBAR REG(FDCAN1_BASE + 0xCCu)
#define SRAMCAN_BASE 0x4000A400u
#define SRAMCAN_RXF0 (SRAMCAN_BASE + 0x0B0u) /* 3 elements of 18 words */
#define SRAMCAN_TXFIFO (SRAMCAN_BASE + 0x278u) /* 3 elements of 18 words */
#define FDCAN_ELEMENT_BYTES 72u

static volatile uint32_t millis;

void SysTick_Handler(void) { millis++; }

static double now_s(void) {
    uint32_t ms, count;
    do { /* a consistent pair: the millisecond did not roll over while the counter was read */
        ms = millis;
        count = REG(SYST_CVR);
    } while (ms != millis);
    uint32_t per_ms = CPU_HZ / 1000u;
    return (double)ms * 1e-3 + (double)(per_ms - 1u - count) / (double)CPU_HZ;
}

static uint32_t adc_read(uint32_t channel) {
    ADC1_SQR1 = channel << 6; /* one conversion of the channel */
    ADC1_CR |= 1u << 2;       /* ADSTART */
    while ((ADC1_ISR & (1u << 2)) == 0u) { /* EOC */
    }
    return ADC1_DR & 0xFFFu;
}

static double sample_position_mm(void *ctx) {
    (void)ctx;
    return (double)adc_read(1u) * LVDT_MM_PER_COUNT;
}

static double sample_current_a(void *ctx) {
    (void)ctx;
    return ((double)adc_read(2u) - CURRENT_ZERO_COUNT) * CURRENT_A_PER_COUNT;
}

static double supply_voltage_v(void *ctx) {
    (void)ctx;
    return (double)adc_read(3u) * SUPPLY_V_PER_COUNT;
}

static void set_drive_v(void *ctx, double drive_v) {
    (void)ctx;
    double supply = supply_voltage_v(ctx);
    double duty = supply > 1.0 ? (drive_v < 0.0 ? -drive_v : drive_v) / supply : 0.0;
    if (duty > 1.0) {
        duty = 1.0;
    }
    TIM1_DIR_GPIO_BSRR = drive_v < 0.0 ? (1u << 16) : 1u; /* reset or set PB0 */
    TIM1_CCR1 = (uint32_t)(duty * (double)PWM_PERIOD);
}

static void can_send(void *ctx, uint32_t can_id, const uint8_t *data, uint8_t length) {
    (void)ctx;
    if (FDCAN_TXFQS & (1u << 21)) { /* TFQF: the TX FIFO is full; the frame is dropped, as a full bus would */
        return;
    }
    uint32_t put = (FDCAN_TXFQS >> 16) & 0x3u;
    volatile uint32_t *element = (volatile uint32_t *)(SRAMCAN_TXFIFO + put * FDCAN_ELEMENT_BYTES);
    uint32_t words[2] = {0u, 0u};
    for (uint8_t i = 0; i < length && i < 8u; i++) {
        words[i / 4u] |= (uint32_t)data[i] << (8u * (i % 4u));
    }
    element[0] = (can_id & 0x7FFu) << 18;   /* standard id */
    element[1] = (uint32_t)length << 16;    /* DLC, classic CAN */
    element[2] = words[0];
    element[3] = words[1];
    FDCAN_TXBAR = 1u << put;
}

static int can_receive(uint32_t *can_id, uint8_t *data, uint8_t *length) {
    if ((FDCAN_RXF0S & 0x7Fu) == 0u) { /* F0FL: nothing waiting */
        return 0;
    }
    uint32_t get = (FDCAN_RXF0S >> 8) & 0x3u;
    volatile uint32_t *element = (volatile uint32_t *)(SRAMCAN_RXF0 + get * FDCAN_ELEMENT_BYTES);
    uint32_t r0 = element[0], r1 = element[1];
    uint32_t words[2] = {element[2], element[3]};
    *can_id = (r0 & (1u << 30)) ? 0xFFFFFFFFu : (r0 >> 18) & 0x7FFu; /* an extended id is never a command */
    *length = (uint8_t)((r1 >> 16) & 0xFu);
    if (*length > 8u) {
        *length = 8u;
    }
    for (uint8_t i = 0; i < *length; i++) {
        data[i] = (uint8_t)(words[i / 4u] >> (8u * (i % 4u)));
    }
    FDCAN_RXF0A = get;
    return 1;
}

static void board_init(void) {
    RCC_AHB2ENR |= (1u << 0) | (1u << 1) | (1u << 13); /* GPIOA, GPIOB, ADC12 */
    RCC_APB1ENR1 |= 1u << 25;                          /* FDCAN */
    RCC_APB2ENR |= 1u << 11;                           /* TIM1 */
    REG(SYST_RVR) = CPU_HZ / 1000u - 1u;
    REG(SYST_CVR) = 0u;
    REG(SYST_CSR) = 0x7u; /* core clock, interrupt, enable */
    ADC1_CR = (ADC1_CR & ~(1u << 29)) | (1u << 28); /* out of deep power-down, regulator on */
    ADC1_CR |= 1u;                                   /* ADEN */
    TIM1_ARR = PWM_PERIOD;
    TIM1_CCR1 = 0u;
    TIM1_CCMR1 = 6u << 4;                 /* PWM mode 1 */
    TIM1_CCER = (1u << 0) | (1u << 2);    /* CC1E, CC1NE */
    TIM1_BDTR = 1u << 15;                 /* MOE */
    TIM1_CR1 = 1u;
    FDCAN_CCCR |= 1u;                      /* INIT */
    while ((FDCAN_CCCR & 1u) == 0u) {
    }
    FDCAN_CCCR |= 1u << 1;                 /* CCE: configuration writable */
    FDCAN_NBTP = (0u << 25) | (19u << 16) | (14u << 8) | 3u; /* 500 kbit/s from a 40 MHz kernel clock */
    FDCAN_CCCR &= ~1u;                     /* leave INIT: on the bus */
}

int main(void) {
    static rig_firmware_t rig;
    static const rig_limits_t limits = {
        .drive_limit_v = 24.0, .over_current_a = 15.0, .travel_min_mm = -0.5, .travel_max_mm = 19.5,
        .lvdt_min_mm = -1.0, .lvdt_max_mm = 21.0, .supply_min_v = 18.0,
        .watchdog_s = 0.020, .heartbeat_period_s = 0.100, .boot_s = 0.200,
    };
    const rig_hardware_t hardware = {sample_position_mm, sample_current_a, set_drive_v, supply_voltage_v, can_send, 0};
    board_init();
    rig_init(&rig, &hardware, &limits, now_s());
    for (;;) {
        uint32_t can_id;
        uint8_t data[8], length;
        while (can_receive(&can_id, data, &length)) {
            rig_on_frame(&rig, can_id, data, length, now_s());
        }
        double now = now_s();
        if (now >= rig_next_deadline_s(&rig)) {
            rig_on_time(&rig, now);
        }
    }
}
