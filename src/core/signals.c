/* Names of the per-sample signals' codes, shared by the host and the controller process. */
#include "rths/signals.h"

const char *rths_rig_fault_name(rths_rig_fault f) {
    switch (f) {
    case RTHS_RIG_OK:
        return "none";
    case RTHS_RIG_FAULT_DISPLACEMENT:
        return "displacement limit";
    case RTHS_RIG_FAULT_FORCE:
        return "force limit";
    case RTHS_RIG_FAULT_DEMAND:
        return "demand limit";
    case RTHS_RIG_FAULT_NONFINITE:
        return "non-finite signal";
    case RTHS_RIG_FAULT_LINK:
        return "link lost";
    case RTHS_RIG_FAULT_WATCHDOG:
        return "watchdog";
    }
    return "unknown fault";
}
