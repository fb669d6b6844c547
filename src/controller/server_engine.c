/* TEMPORARY stub engine (until the controller step and plant land): a target-following "rig"
 * with exact Fourier sums, enough to exercise pacing, the link and the safety logic. */
#include "controller/server_engine.h"

#include "rths/setup.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#define PRING 256

struct rths_engine {
    double h;
    uint64_t n;
    int armed, fault;
    double f, amp, w, phase;
    int harmonics;
    double a[RTHS_PROTO_HARMONICS], b[RTHS_PROTO_HARMONICS];
    double gain; /* excitation ramp 0..1 */
    /* period accumulation */
    int acc_n;
    double acc_start;
    rths_proto_fourier sp, sn, sf;
    uint32_t index;
    rths_proto_period ring[PRING];
    _Atomic size_t head, tail;
};

int rths_engine_create(rths_config *cfg, rths_engine **out, rths_engine_info *info,
                       rths_error *err) {
    if (cfg) {
        rths_setup setup;
        int rc = rths_setup_read(cfg, &setup, err);
        if (rc) return rc;
        rths_setup_free(&setup);
    }
    rths_engine *e = calloc(1, sizeof *e);
    if (!e) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    e->h = 1e-4;
    info->sample_period_s = e->h;
    info->noise_level_m = 0.0;
    info->max_harmonics = RTHS_PROTO_HARMONICS;
    info->ramp_time_s = 0.1;
    strcpy(info->description, "stub engine");
    *out = e;
    return RTHS_OK;
}

void rths_engine_destroy(rths_engine *e) {
    free(e);
}

static double target_at(const rths_engine *e, double ph) {
    double x = 0;
    for (int k = 0; k < e->harmonics; k++)
        x += e->a[k] * cos((k + 1) * ph) + e->b[k] * sin((k + 1) * ph);
    return x;
}

void rths_engine_step(rths_engine *e, rths_proto_trace_sample *sig) {
    double t = (double)e->n * e->h;
    double g_target = e->armed ? 1.0 : 0.0;
    double dg = e->h / 0.1;
    e->gain = g_target > e->gain ? fmin(1.0, e->gain + dg) : fmax(0.0, e->gain - dg);
    double xp = e->gain * target_at(e, e->phase);
    double xn = xp;
    double force = e->gain * e->amp * sin(e->phase);
    sig->time_s = t;
    sig->x_phys_m = xp;
    sig->x_num_m = xn;
    sig->target_m = xp;
    sig->force_n = force;
    sig->demand = force * 0.1;
    if (e->w > 0) {
        if (e->acc_n == 0) {
            memset(&e->sp, 0, sizeof e->sp);
            memset(&e->sn, 0, sizeof e->sn);
            memset(&e->sf, 0, sizeof e->sf);
            e->acc_start = t;
        }
        for (int k = 0; k <= RTHS_PROTO_HARMONICS; k++) {
            double c = cos(k * e->phase), s = sin(k * e->phase);
            e->sp.a[k] += xp * c;
            e->sp.b[k] += xp * s;
            e->sn.a[k] += xn * c;
            e->sn.b[k] += xn * s;
            e->sf.a[k] += force * c;
            e->sf.b[k] += force * s;
        }
        e->acc_n++;
        e->phase += e->w * e->h;
        if (e->phase >= 2 * M_PI) {
            e->phase -= 2 * M_PI;
            rths_proto_period p;
            memset(&p, 0, sizeof p);
            p.index = e->index++;
            p.frequency_hz = e->f;
            p.start_time_s = e->acc_start;
            p.end_time_s = t + e->h;
            p.samples = (uint32_t)e->acc_n;
            for (int k = 0; k <= RTHS_PROTO_HARMONICS; k++) {
                double sc = (k ? 2.0 : 1.0) / e->acc_n;
                p.phys.a[k] = e->sp.a[k] * sc;
                p.phys.b[k] = k ? e->sp.b[k] * sc : 0;
                p.num.a[k] = e->sn.a[k] * sc;
                p.num.b[k] = k ? e->sn.b[k] * sc : 0;
                p.force.a[k] = e->sf.a[k] * sc;
                p.force.b[k] = k ? e->sf.b[k] * sc : 0;
            }
            size_t h = atomic_load_explicit(&e->head, memory_order_relaxed);
            if (h - atomic_load_explicit(&e->tail, memory_order_acquire) < PRING) {
                e->ring[h % PRING] = p;
                atomic_store_explicit(&e->head, h + 1, memory_order_release);
            }
            e->acc_n = 0;
        }
    }
    if (e->armed && fabs(xp) > 0.01) {
        e->fault = 1;
        e->armed = 0;
    }
    e->n++;
}

int rths_engine_arm(rths_engine *e) {
    if (e->fault) return RTHS_PROTO_ESTATE;
    e->armed = 1;
    return 0;
}
void rths_engine_disarm(rths_engine *e) {
    e->armed = 0;
}
void rths_engine_trip_watchdog(rths_engine *e) {
    e->armed = 0;
    e->fault = 6;
}
void rths_engine_set_forcing(rths_engine *e, double f, double a) {
    e->f = f;
    e->amp = a;
    e->w = 2 * M_PI * f;
    e->acc_n = 0;
}
void rths_engine_set_target(rths_engine *e, int h, const double *a, const double *b) {
    e->harmonics = h;
    for (int k = 0; k < h; k++) {
        e->a[k] = a[k];
        e->b[k] = b[k];
    }
    e->acc_n = 0;
}
void rths_engine_reset_fault(rths_engine *e) {
    e->fault = 0;
}
int rths_engine_armed(const rths_engine *e) {
    return e->armed;
}
int rths_engine_fault(const rths_engine *e) {
    return e->fault;
}
double rths_engine_time_s(const rths_engine *e) {
    return (double)e->n * e->h;
}

int rths_engine_pop_period(rths_engine *e, rths_proto_period *out) {
    size_t t = atomic_load_explicit(&e->tail, memory_order_relaxed);
    if (t == atomic_load_explicit(&e->head, memory_order_acquire)) return 0;
    *out = e->ring[t % PRING];
    atomic_store_explicit(&e->tail, t + 1, memory_order_release);
    return 1;
}
long rths_engine_dropped_periods(const rths_engine *e) {
    (void)e;
    return 0;
}
