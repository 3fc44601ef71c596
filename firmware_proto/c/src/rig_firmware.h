/*
 * The rig side of ICD v1 as a state machine: the C port of firmware_proto/firmware.py.
 *
 * Portable C99, no dynamic memory. Frames in, frames out, time passed in explicitly (seconds since power-up,
 * any monotonic base). The hardware sits behind rig_hardware_t: the same core runs in the host build (the
 * simulated rig loads it with ctypes) and on a microcontroller (hal/). The frame layouts come from the DBC
 * through cantools' C generator (build/generated/icd_v1.h); the behaviour is firmware_proto/PROTOCOL.md's.
 */
#ifndef RIG_FIRMWARE_H
#define RIG_FIRMWARE_H

#include <stdbool.h>
#include <stdint.h>

#define RIG_FW_MAJOR 1u
#define RIG_FW_MINOR 0u

enum rig_state { RIG_BOOT = 0, RIG_READY = 1, RIG_RUNNING = 2, RIG_FAULT = 3 };

enum rig_fault_code {
    RIG_FAULT_NONE = 0, RIG_FAULT_WATCHDOG = 1, RIG_FAULT_OVER_CURRENT = 2, RIG_FAULT_LVDT = 3,
    RIG_FAULT_TRAVEL_LIMIT = 4, RIG_FAULT_SUPPLY_LOW = 5
};

/* Bits of rig_flags(): the latched fault flags RIG_FEEDBACK carries. */
enum rig_flag { RIG_FLAG_WATCHDOG = 1, RIG_FLAG_OVER_CURRENT = 2, RIG_FLAG_LVDT = 4, RIG_FLAG_TRAVEL = 8 };

/* Indices of rig_counter(). */
enum rig_counter_index {
    RIG_COUNT_ACCEPTED, RIG_COUNT_BAD_CRC, RIG_COUNT_BAD_LENGTH, RIG_COUNT_BAD_MODE, RIG_COUNT_REPEATED,
    RIG_COUNT_STALE, RIG_COUNT_IGNORED_IN_BOOT, RIG_COUNT_WATCHDOG_TRIPS, RIG_COUNT_FAULTS_BY_CODE, /* + code */
    RIG_COUNTERS = RIG_COUNT_FAULTS_BY_CODE + 6
};

/* What the firmware needs of the rig's hardware. Each call gets ctx back. */
typedef struct {
    double (*sample_position_mm)(void *ctx);  /* the LVDT rack position (NaN: the LVDT reads nothing) */
    double (*sample_current_a)(void *ctx);    /* the coil current */
    void (*set_drive_v)(void *ctx, double drive_v);  /* the amplifier's drive (0 V: the safe state) */
    double (*supply_voltage_v)(void *ctx);    /* the amplifier supply */
    void (*send)(void *ctx, uint32_t can_id, const uint8_t *data, uint8_t length);  /* a CAN frame out */
    void *ctx;
} rig_hardware_t;

/* Limits and timing (FirmwareLimits in firmware.py). */
typedef struct {
    double drive_limit_v, over_current_a, travel_min_mm, travel_max_mm, lvdt_min_mm, lvdt_max_mm, supply_min_v;
    double watchdog_s, heartbeat_period_s, boot_s;
} rig_limits_t;

typedef struct {
    rig_hardware_t hw;
    rig_limits_t limits;
    uint8_t state, fault_code, flags;
    bool heartbeat_enabled;
    bool have_last_counter;
    uint8_t last_counter;
    double boot_done_s, next_heartbeat_s, watchdog_due_s;
    uint32_t counters[RIG_COUNTERS];
} rig_firmware_t;

void rig_init(rig_firmware_t *fw, const rig_hardware_t *hw, const rig_limits_t *limits, double start_s);
/* The earliest time at which rig_on_time has something to do. */
double rig_next_deadline_s(const rig_firmware_t *fw);
/* Run the timers due at now_s: boot, watchdog, heartbeat. */
void rig_on_time(rig_firmware_t *fw, double now_s);
/* Tell the firmware its main loop was held up until now_s: one heartbeat on resuming, not a burst. */
void rig_skip_missed_heartbeats(rig_firmware_t *fw, double now_s);
/* One received frame: a valid BENCH_CMD gets its RIG_FEEDBACK (and a heartbeat if the state changed). */
void rig_on_frame(rig_firmware_t *fw, uint32_t can_id, const uint8_t *data, uint8_t length, double now_s);
/* Latch a fault from outside the protocol (a hardware monitor, or a test). */
void rig_force_fault(rig_firmware_t *fw, uint8_t code);

/* For bindings that do not mirror the struct (ctypes): its size and its fields. */
uint32_t rig_firmware_size(void);
uint8_t rig_state(const rig_firmware_t *fw);
uint8_t rig_fault(const rig_firmware_t *fw);
uint8_t rig_flags(const rig_firmware_t *fw);
uint32_t rig_counter(const rig_firmware_t *fw, uint32_t index);
void rig_set_heartbeat_enabled(rig_firmware_t *fw, bool enabled);

/* CRC-8/SAE-J1850 of ICD v1's E2E protection: over the data id, then payload bytes 1..7. */
uint8_t rig_e2e_crc(uint8_t data_id, const uint8_t payload[8]);

#endif
