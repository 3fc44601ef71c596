/* The rig side of ICD v1: see rig_firmware.h and firmware_proto/PROTOCOL.md. */
#include "rig_firmware.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

#include "icd_v1.h"

#define DATA_ID(frame_id) ((uint8_t)((frame_id) & 0xFFu))
#define MAX_PENDING 4 /* heartbeats a command can cause: a trip, a state change */

typedef struct {
    uint8_t data[MAX_PENDING][8];
    int count;
} pending_t;

static double clamp(double value, double low, double high) {
    return value < low ? low : (value > high ? high : value);
}

uint8_t rig_e2e_crc(uint8_t data_id, const uint8_t payload[8]) {
    uint8_t crc = 0xFFu;
    uint8_t byte = data_id;
    for (int i = 0; i < 8; i++) {
        if (i > 0) {
            byte = payload[i];
        }
        crc ^= byte;
        for (int bit = 0; bit < 8; bit++) {
            crc = (crc & 0x80u) ? (uint8_t)((crc << 1) ^ 0x1Du) : (uint8_t)(crc << 1);
        }
    }
    return (uint8_t)(crc ^ 0xFFu);
}

static void heartbeat(rig_firmware_t *fw, uint8_t out[8]) {
    struct icd_v1_rig_heartbeat_t msg;
    icd_v1_rig_heartbeat_init(&msg);
    msg.state = fw->state;
    msg.fault_code = fw->fault_code;
    msg.fw_major = RIG_FW_MAJOR;
    msg.fw_minor = RIG_FW_MINOR;
    msg.supply_voltage = icd_v1_rig_heartbeat_supply_voltage_encode(
        clamp(fw->hw.supply_voltage_v(fw->hw.ctx), 0.0, 655.35));
    memset(out, 0, 8);
    (void)icd_v1_rig_heartbeat_pack(out, &msg, 8);
}

static void send_heartbeat_now(rig_firmware_t *fw) {
    uint8_t data[8];
    heartbeat(fw, data);
    fw->hw.send(fw->hw.ctx, ICD_V1_RIG_HEARTBEAT_FRAME_ID, data, 8);
}

/* A state change is announced at once: now, or (while a command is handled) after its reply. */
static void enter(rig_firmware_t *fw, uint8_t state, pending_t *pending) {
    fw->state = state;
    if (!fw->heartbeat_enabled) {
        return;
    }
    if (pending != NULL && pending->count < MAX_PENDING) {
        heartbeat(fw, pending->data[pending->count++]);
    } else {
        send_heartbeat_now(fw);
    }
}

static void trip(rig_firmware_t *fw, uint8_t code, pending_t *pending) {
    fw->hw.set_drive_v(fw->hw.ctx, 0.0);
    fw->watchdog_due_s = INFINITY;
    if (code < 6) {
        fw->counters[RIG_COUNT_FAULTS_BY_CODE + code]++;
    }
    if (fw->fault_code == RIG_FAULT_NONE) {
        fw->fault_code = code; /* the first cause is the one reported */
    }
    if (fw->state != RIG_FAULT) {
        enter(fw, RIG_FAULT, pending);
    }
}

void rig_init(rig_firmware_t *fw, const rig_hardware_t *hw, const rig_limits_t *limits, double start_s) {
    memset(fw, 0, sizeof(*fw));
    fw->hw = *hw;
    fw->limits = *limits;
    fw->state = RIG_BOOT;
    fw->fault_code = RIG_FAULT_NONE;
    fw->heartbeat_enabled = true;
    fw->boot_done_s = start_s + limits->boot_s;
    fw->next_heartbeat_s = start_s;
    fw->watchdog_due_s = INFINITY;
    fw->hw.set_drive_v(fw->hw.ctx, 0.0);
}

double rig_next_deadline_s(const rig_firmware_t *fw) {
    double deadline = fw->next_heartbeat_s < fw->watchdog_due_s ? fw->next_heartbeat_s : fw->watchdog_due_s;
    if (fw->state == RIG_BOOT && fw->boot_done_s < deadline) {
        deadline = fw->boot_done_s;
    }
    return deadline;
}

/* The first heartbeat time on the grid from power-up later than now_s. */
static double heartbeat_after(const rig_firmware_t *fw, double now_s) {
    double period = fw->limits.heartbeat_period_s;
    double missed = floor((now_s - fw->next_heartbeat_s) / period);
    return fw->next_heartbeat_s + (missed + 1.0) * period;
}

void rig_on_time(rig_firmware_t *fw, double now_s) {
    if (fw->state == RIG_BOOT && now_s >= fw->boot_done_s) {
        enter(fw, RIG_READY, NULL);
    }
    if (now_s >= fw->watchdog_due_s) {
        fw->watchdog_due_s = INFINITY;
        fw->counters[RIG_COUNT_WATCHDOG_TRIPS]++;
        fw->flags |= RIG_FLAG_WATCHDOG;
        trip(fw, RIG_FAULT_WATCHDOG, NULL);
    }
    if (now_s >= fw->next_heartbeat_s) {
        if (fw->heartbeat_enabled) {
            send_heartbeat_now(fw);
        }
        /* keep the 10 Hz grid; skip missed beats rather than bursting them */
        fw->next_heartbeat_s = heartbeat_after(fw, now_s);
    }
}

void rig_skip_missed_heartbeats(rig_firmware_t *fw, double now_s) {
    if (now_s >= fw->next_heartbeat_s + fw->limits.heartbeat_period_s) {
        fw->next_heartbeat_s = heartbeat_after(fw, now_s) - fw->limits.heartbeat_period_s;
    }
}

static bool counter_is_new(rig_firmware_t *fw, uint8_t counter, uint8_t mode) {
    if (fw->have_last_counter) {
        uint8_t delta = (uint8_t)(counter - fw->last_counter);
        if (delta == 0) {
            fw->counters[RIG_COUNT_REPEATED]++;
            return false;
        }
        /* while the amplifier is off, a SAFE command may resynchronise the counter */
        if (delta >= 128 && !(mode == ICD_V1_BENCH_CMD_MODE_SAFE_CHOICE && fw->state != RIG_RUNNING)) {
            fw->counters[RIG_COUNT_STALE]++;
            return false;
        }
    }
    fw->have_last_counter = true;
    fw->last_counter = counter;
    return true;
}

static void check_samples(rig_firmware_t *fw, double position_mm, double current_a, pending_t *pending) {
    const rig_limits_t *lim = &fw->limits;
    if (!(position_mm >= lim->lvdt_min_mm && position_mm <= lim->lvdt_max_mm)) { /* also catches NaN */
        fw->flags |= RIG_FLAG_LVDT;
        trip(fw, RIG_FAULT_LVDT, pending);
    } else if (!(position_mm >= lim->travel_min_mm && position_mm <= lim->travel_max_mm)) {
        fw->flags |= RIG_FLAG_TRAVEL;
        trip(fw, RIG_FAULT_TRAVEL_LIMIT, pending);
    }
    if (!(fabs(current_a) <= lim->over_current_a)) { /* also catches NaN */
        fw->flags |= RIG_FLAG_OVER_CURRENT;
        trip(fw, RIG_FAULT_OVER_CURRENT, pending);
    }
    if (fw->hw.supply_voltage_v(fw->hw.ctx) < lim->supply_min_v) {
        trip(fw, RIG_FAULT_SUPPLY_LOW, pending);
    }
}

static void feedback(const rig_firmware_t *fw, uint8_t counter, double position_mm, double current_a,
                     uint8_t out[8]) {
    struct icd_v1_rig_feedback_t msg;
    icd_v1_rig_feedback_init(&msg);
    /* out-of-range samples are clamped to what the frame carries; the fault flags say they were not valid */
    position_mm = isnan(position_mm) ? 0.0 : clamp(position_mm, 0.0, 65.535);
    current_a = isnan(current_a) ? 0.0 : clamp(current_a, -32.768, 32.767);
    msg.counter = counter;
    msg.amp_enabled = fw->state == RIG_RUNNING;
    msg.watchdog_tripped = (fw->flags & RIG_FLAG_WATCHDOG) != 0;
    msg.over_current = (fw->flags & RIG_FLAG_OVER_CURRENT) != 0;
    msg.lvdt_fault = (fw->flags & RIG_FLAG_LVDT) != 0;
    msg.travel_limit = (fw->flags & RIG_FLAG_TRAVEL) != 0;
    msg.rack_position = icd_v1_rig_feedback_rack_position_encode(position_mm);
    msg.coil_current = icd_v1_rig_feedback_coil_current_encode(current_a);
    memset(out, 0, 8);
    (void)icd_v1_rig_feedback_pack(out, &msg, 8);
    out[0] = rig_e2e_crc(DATA_ID(ICD_V1_RIG_FEEDBACK_FRAME_ID), out);
}

void rig_on_frame(rig_firmware_t *fw, uint32_t can_id, const uint8_t *data, uint8_t length, double now_s) {
    struct icd_v1_bench_cmd_t cmd;
    pending_t pending = {.count = 0};
    uint8_t reply[8];

    if (can_id != ICD_V1_BENCH_CMD_FRAME_ID) {
        return;
    }
    /* the checks, in PROTOCOL.md's order: length, CRC, Mode, then (not in BOOT) the counter */
    if (length != ICD_V1_BENCH_CMD_LENGTH) {
        fw->counters[RIG_COUNT_BAD_LENGTH]++;
        return;
    }
    if (data[0] != rig_e2e_crc(DATA_ID(ICD_V1_BENCH_CMD_FRAME_ID), data)) {
        fw->counters[RIG_COUNT_BAD_CRC]++;
        return;
    }
    (void)icd_v1_bench_cmd_unpack(&cmd, data, length);
    if (cmd.mode != ICD_V1_BENCH_CMD_MODE_SAFE_CHOICE && cmd.mode != ICD_V1_BENCH_CMD_MODE_RUN_CHOICE) {
        fw->counters[RIG_COUNT_BAD_MODE]++;
        return;
    }
    if (fw->state == RIG_BOOT) {
        fw->counters[RIG_COUNT_IGNORED_IN_BOOT]++;
        return;
    }
    if (!counter_is_new(fw, cmd.counter, cmd.mode)) {
        return;
    }
    fw->counters[RIG_COUNT_ACCEPTED]++;

    /* samples are taken before the new drive is applied (ICD 3.1) */
    double position_mm = fw->hw.sample_position_mm(fw->hw.ctx);
    double current_a = fw->hw.sample_current_a(fw->hw.ctx);
    check_samples(fw, position_mm, current_a, &pending);

    if (cmd.mode == ICD_V1_BENCH_CMD_MODE_SAFE_CHOICE) {
        fw->hw.set_drive_v(fw->hw.ctx, 0.0);
        fw->watchdog_due_s = INFINITY;
        if (fw->state == RIG_FAULT) {
            fw->flags = 0;
            fw->fault_code = RIG_FAULT_NONE;
        }
        if (fw->state != RIG_READY) {
            enter(fw, RIG_READY, &pending);
        }
    } else if (fw->state != RIG_FAULT) {
        double limit = fw->limits.drive_limit_v;
        fw->hw.set_drive_v(fw->hw.ctx, clamp(icd_v1_bench_cmd_drive_voltage_decode(cmd.drive_voltage), -limit, limit));
        fw->watchdog_due_s = now_s + fw->limits.watchdog_s;
        if (fw->state == RIG_READY) {
            enter(fw, RIG_RUNNING, &pending);
        }
    }
    /* RUN while FAULT: the drive stays at 0 V; the reply shows why */

    feedback(fw, cmd.counter, position_mm, current_a, reply);
    fw->hw.send(fw->hw.ctx, ICD_V1_RIG_FEEDBACK_FRAME_ID, reply, 8);
    for (int i = 0; i < pending.count; i++) {
        fw->hw.send(fw->hw.ctx, ICD_V1_RIG_HEARTBEAT_FRAME_ID, pending.data[i], 8);
    }
}

void rig_force_fault(rig_firmware_t *fw, uint8_t code) {
    trip(fw, code, NULL);
}

uint32_t rig_firmware_size(void) { return (uint32_t)sizeof(rig_firmware_t); }
uint8_t rig_state(const rig_firmware_t *fw) { return fw->state; }
uint8_t rig_fault(const rig_firmware_t *fw) { return fw->fault_code; }
uint8_t rig_flags(const rig_firmware_t *fw) { return fw->flags; }
uint32_t rig_counter(const rig_firmware_t *fw, uint32_t index) {
    return index < RIG_COUNTERS ? fw->counters[index] : 0u;
}
void rig_set_heartbeat_enabled(rig_firmware_t *fw, bool enabled) { fw->heartbeat_enabled = enabled; }
