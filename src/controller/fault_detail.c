/* The text of a latched fault (controller.h, rths_fault_detail_format): every fault message
 * names the channel, the value and the limit (docs/protocol.md, STATUS's fault detail). */
#include "rths/controller.h"

#include <stdio.h>

void rths_fault_detail_format(const rths_fault_detail *d, char *out, size_t cap) {
    if (!cap) return;
    const char *name = rths_rig_fault_name((rths_rig_fault)d->fault);
    const int ch = d->channel;
    switch ((rths_fault_cause)d->cause) {
    case RTHS_FAULT_CAUSE_DISPLACEMENT_LIMIT:
        snprintf(out, cap, "%s: the laser on DoF %d reads %.4g m, beyond +-%g m", name, ch,
                 d->value, d->limit);
        return;
    case RTHS_FAULT_CAUSE_FORCE_LIMIT:
        snprintf(out, cap, "%s: the load cell of actuator %d reads %.4g N, beyond +-%g N", name, ch,
                 d->value, d->limit);
        return;
    case RTHS_FAULT_CAUSE_DEMAND_LIMIT:
        snprintf(out, cap, "%s: actuator %d demand %.4g V, beyond +-%g V", name, ch, d->value,
                 d->limit);
        return;
    case RTHS_FAULT_CAUSE_NONFINITE_LASER:
        if (ch > 0)
            snprintf(out, cap, "%s: the laser on DoF %d reads %g", name, ch, d->value);
        else
            snprintf(out, cap, "%s: a sensor reading is not finite", name);
        return;
    case RTHS_FAULT_CAUSE_NONFINITE_ACCELEROMETER:
        snprintf(out, cap, "%s: the accelerometer of actuator %d reads %g", name, ch, d->value);
        return;
    case RTHS_FAULT_CAUSE_NONFINITE_LOAD_CELL:
        snprintf(out, cap, "%s: the load cell of actuator %d reads %g", name, ch, d->value);
        return;
    case RTHS_FAULT_CAUSE_NONFINITE_NUMERICAL:
        snprintf(out, cap,
                 "%s: the numerical substructure's interface DoF %d became %g (its integration "
                 "diverged)",
                 name, ch, d->value);
        return;
    case RTHS_FAULT_CAUSE_NONFINITE_DEMAND:
        snprintf(out, cap, "%s: actuator %d demand became %g", name, ch, d->value);
        return;
    case RTHS_FAULT_CAUSE_DEVICE:
        snprintf(out, cap,
                 "%s: reported by the I/O device (its own limit; the device names the "
                 "channel in its log)",
                 name);
        return;
    case RTHS_FAULT_CAUSE_HOST_SILENT:
        snprintf(out, cap, "%s: the host was silent for %.6g s, beyond server.watchdog_s = %g s",
                 name, d->value, d->limit);
        return;
    case RTHS_FAULT_CAUSE_LOOP_STALLED:
        snprintf(out, cap,
                 "%s: the loop stalled: a sample ran %.3g s, beyond its deadline plus "
                 "server.stall_margin_s (%g s); the I/O plug-in's safe state was driven (restart "
                 "the controller)",
                 name, d->value, d->limit);
        return;
    case RTHS_FAULT_CAUSE_NONE:
    case RTHS_FAULT_CAUSE_EXTERNAL:
        break;
    }
    snprintf(out, cap, "%s", d->fault ? name : "no fault");
}
