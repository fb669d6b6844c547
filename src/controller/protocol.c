/* Frame codec of the host <-> controller link (docs/protocol.md). Pure functions, no I/O.
 *
 * Writing and reading go through explicit byte-order helpers rather than struct overlays, so the
 * wire format does not depend on the compiler's padding or the host's endianness. */
#include "rths/protocol.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

const double rths_proto_latency_edges_s[RTHS_PROTO_LATENCY_BINS] = {
    1e-6,   2e-6, 5e-6, 10e-6, 20e-6, 50e-6, 100e-6, 200e-6,
    500e-6, 1e-3, 2e-3, 5e-3,  10e-3, 20e-3, 50e-3,  INFINITY};

int rths_proto_status_is_fatal(int status) {
    return status == RTHS_PROTO_EMAGIC || status == RTHS_PROTO_EVERSION ||
           status == RTHS_PROTO_EOVERSIZE || status == RTHS_PROTO_ECRC;
}

const char *rths_proto_status_name(int status) {
    switch (status) {
    case RTHS_PROTO_OK:
        return "ok";
    case RTHS_PROTO_INCOMPLETE:
        return "incomplete frame";
    case RTHS_PROTO_EMAGIC:
        return "bad magic (not a frame start)";
    case RTHS_PROTO_EVERSION:
        return "unsupported protocol version";
    case RTHS_PROTO_EOVERSIZE:
        return "payload length above the maximum";
    case RTHS_PROTO_ECRC:
        return "checksum mismatch";
    case RTHS_PROTO_ETYPE:
        return "unknown message type";
    case RTHS_PROTO_EPAYLOAD:
        return "malformed payload";
    case RTHS_PROTO_EBUSY:
        return "controller busy with another client";
    case RTHS_PROTO_ESTATE:
        return "command not valid in this state";
    case RTHS_PROTO_ERANGE:
        return "value out of range";
    case RTHS_PROTO_ENODATA:
        return "no data yet";
    }
    return "unknown status";
}

const char *rths_msg_type_name(int type) {
    switch (type) {
#define TYPE_NAME(name, code, direction, reply)                                                    \
    case code:                                                                                     \
        return #name;
        RTHS_PROTO_MESSAGES(TYPE_NAME)
#undef TYPE_NAME
    }
    return "unknown";
}

uint32_t rths_crc32(const uint8_t *data, size_t len) {
    /* Bitwise: frames are at most ~1 KiB and only the network thread checksums, so a table
     * (and its initialisation race) buys nothing. */
    uint32_t crc = 0xFFFFFFFFu;
    for (size_t i = 0; i < len; i++) {
        crc ^= data[i];
        for (int k = 0; k < 8; k++)
            crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
    }
    return crc ^ 0xFFFFFFFFu;
}

/* ---- writer ---- */

typedef struct {
    uint8_t *p;
    size_t n, cap;
    int bad;
} writer;

static void w_bytes(writer *w, const void *src, size_t n) {
    if (w->bad || n > w->cap - w->n) {
        w->bad = 1;
        return;
    }
    memcpy(w->p + w->n, src, n);
    w->n += n;
}

static void w_u8(writer *w, unsigned v) {
    uint8_t b = (uint8_t)v;
    w_bytes(w, &b, 1);
}

static void w_u16(writer *w, unsigned v) {
    uint8_t b[2] = {(uint8_t)v, (uint8_t)(v >> 8)};
    w_bytes(w, b, 2);
}

static void w_u32(writer *w, uint32_t v) {
    uint8_t b[4];
    for (int i = 0; i < 4; i++)
        b[i] = (uint8_t)(v >> (8 * i));
    w_bytes(w, b, 4);
}

static void w_u64(writer *w, uint64_t v) {
    uint8_t b[8];
    for (int i = 0; i < 8; i++)
        b[i] = (uint8_t)(v >> (8 * i));
    w_bytes(w, b, 8);
}

static void w_f64(writer *w, double v) {
    if (!isfinite(v)) {
        w->bad = 1;
        return;
    }
    uint64_t u;
    memcpy(&u, &v, sizeof u);
    w_u64(w, u);
}

static void w_text(writer *w, const char *s) {
    size_t n = strnlen(s, RTHS_PROTO_MAX_TEXT + 1);
    if (n > RTHS_PROTO_MAX_TEXT) {
        w->bad = 1;
        return;
    }
    w_u8(w, (unsigned)n);
    w_bytes(w, s, n);
}

/* Field encoders, one per wire kind of the message list (protocol.h). */
static void enc_u8(writer *w, const uint8_t *v) {
    w_u8(w, *v);
}
static void enc_u16(writer *w, const uint16_t *v) {
    w_u16(w, *v);
}
static void enc_u32(writer *w, const uint32_t *v) {
    w_u32(w, *v);
}
static void enc_u64(writer *w, const uint64_t *v) {
    w_u64(w, *v);
}
static void enc_f64(writer *w, const double *v) {
    w_f64(w, *v);
}
static void enc_text(writer *w, const char (*v)[RTHS_PROTO_MAX_TEXT + 1]) {
    w_text(w, *v);
}
static void enc_fourier(writer *w, const rths_proto_fourier *f) {
    for (int k = 0; k <= RTHS_PROTO_HARMONICS; k++)
        w_f64(w, f->a[k]);
    for (int k = 0; k <= RTHS_PROTO_HARMONICS; k++)
        w_f64(w, f->b[k]);
}
static void enc_latency_hist(writer *w, const uint64_t (*h)[RTHS_PROTO_LATENCY_BINS]) {
    for (int i = 0; i < RTHS_PROTO_LATENCY_BINS; i++)
        w_u64(w, (*h)[i]);
}
/* A DoF count as sent: 0 (a message built for one DoF) is 1; above the maximum is invalid. */
static unsigned w_dofs(writer *w, int n) {
    if (n < 0 || n > RTHS_PROTO_MAX_DOFS) {
        w->bad = 1;
        return 1;
    }
    unsigned d = n ? (unsigned)n : 1u;
    w_u8(w, d);
    return d;
}
static void enc_dof_values(writer *w, const rths_proto_dof_values *v) {
    unsigned n = w_dofs(w, v->n);
    for (unsigned d = 0; d < n && !w->bad; d++)
        w_f64(w, v->v[d]);
}
static void enc_target_dofs(writer *w, const rths_proto_target *t) {
    unsigned n = w_dofs(w, t->dofs);
    if (t->harmonics < 0 || t->harmonics > RTHS_PROTO_HARMONICS) {
        w->bad = 1;
        return;
    }
    const int h = t->harmonics;
    w_u8(w, (unsigned)h);
    for (unsigned d = 0; d < n && !w->bad; d++) {
        for (int k = 0; k < h; k++)
            w_f64(w, t->a[d * (unsigned)h + (unsigned)k]);
        for (int k = 0; k < h; k++)
            w_f64(w, t->b[d * (unsigned)h + (unsigned)k]);
    }
}
static void enc_period_dofs(writer *w, const rths_proto_period *p) {
    unsigned n = w_dofs(w, p->interface_dofs);
    for (unsigned d = 0; d < n && !w->bad; d++) {
        enc_fourier(w, d ? &p->phys_dof[d] : &p->phys);
        enc_fourier(w, d ? &p->num_dof[d] : &p->num);
        enc_fourier(w, d ? &p->force_dof[d] : &p->force);
    }
}
/* The optional last block of a PERIOD: absent for none (one encoding per message), else 1..16. */
static void enc_output_dofs(writer *w, const rths_proto_period *p) {
    if (!p->output_dofs) return;
    if (p->output_dofs < 0 || p->output_dofs > RTHS_PROTO_MAX_OUTPUT_DOFS) {
        w->bad = 1;
        return;
    }
    w_u8(w, (unsigned)p->output_dofs);
    for (int j = 0; j < p->output_dofs && !w->bad; j++)
        enc_fourier(w, &p->output_dof[j]);
}
static void enc_trace_batch(writer *w, const rths_proto_trace *t) {
    unsigned n = w_dofs(w, t->dofs);
    if (t->count < 1 || t->count > RTHS_PROTO_MAX_TRACE_BATCH) {
        w->bad = 1;
        return;
    }
    w_u8(w, (unsigned)t->count);
    for (int i = 0; i < t->count && !w->bad; i++) {
        const rths_proto_trace_sample *s = &t->s[i];
        w_f64(w, s->time_s);
        for (unsigned d = 0; d < n; d++) {
            const double v[5] = {
                d ? s->x_phys_dof_m[d] : s->x_phys_m, d ? s->x_num_dof_m[d] : s->x_num_m,
                d ? s->target_dof_m[d] : s->target_m, d ? s->force_dof_n[d] : s->force_n,
                d ? s->demand_dof[d] : s->demand};
            for (int j = 0; j < 5; j++)
                w_f64(w, v[j]);
        }
    }
}

/* Constraints beyond the field kinds; both directions refuse what this refuses. */
static int payload_valid(const rths_msg *m) {
    if (m->type == RTHS_MSG_PERIOD)
        return m->u.period.late_samples <= m->u.period.samples &&
               m->u.period.clipped_demand_samples <= m->u.period.samples &&
               m->u.period.saturated_sensor_samples <= m->u.period.samples;
    if (m->type == RTHS_MSG_SUBSCRIBE)
        return !(m->u.subscribe.flags & ~(RTHS_SUBSCRIBE_PERIODS | RTHS_SUBSCRIBE_TRACES)) &&
               m->u.subscribe.trace_decimation >= 1;
    if (m->type == RTHS_MSG_HELLO_REPLY)
        return m->u.hello_reply.interface_dofs >= 1 &&
               m->u.hello_reply.interface_dofs <= RTHS_PROTO_MAX_DOFS;
    return 1;
}

#define ENCODE_FIELD(kind, member, doc) enc_##kind(w, &m->u.member);
#define ENCODE_CASE(name, code, direction, reply)                                                  \
    case code:                                                                                     \
        RTHS_PROTO_PAYLOAD_##name(ENCODE_FIELD) break;

static void encode_payload(writer *w, const rths_msg *m) {
    if (!payload_valid(m)) {
        w->bad = 1;
        return;
    }
    switch (m->type) {
        RTHS_PROTO_MESSAGES(ENCODE_CASE)
    default:
        w->bad = 1;
    }
}

static size_t encode_as(const rths_msg *msg, int version, uint8_t *buf, size_t cap) {
    if (!msg || !buf || cap < RTHS_PROTO_HEADER_SIZE + RTHS_PROTO_CRC_SIZE) return 0;
    /* The payload is written straight after the header's slot; the header is filled afterwards,
     * once the length is known. The payload may not use the CRC's 4 bytes. */
    size_t room = cap - RTHS_PROTO_HEADER_SIZE - RTHS_PROTO_CRC_SIZE;
    if (room > RTHS_PROTO_MAX_PAYLOAD) room = RTHS_PROTO_MAX_PAYLOAD;
    writer pw = {buf + RTHS_PROTO_HEADER_SIZE, 0, room, 0};
    encode_payload(&pw, msg);
    if (pw.bad) return 0;
    writer hw = {buf, 0, RTHS_PROTO_HEADER_SIZE, 0};
    w_u8(&hw, RTHS_PROTO_MAGIC0);
    w_u8(&hw, RTHS_PROTO_MAGIC1);
    w_u8(&hw, (unsigned)version);
    w_u8(&hw, msg->type);
    w_u16(&hw, msg->seq);
    w_u16(&hw, (unsigned)pw.n);
    size_t body = RTHS_PROTO_HEADER_SIZE + pw.n;
    writer cw = {buf + body, 0, RTHS_PROTO_CRC_SIZE, 0};
    w_u32(&cw, rths_crc32(buf, body));
    return body + RTHS_PROTO_CRC_SIZE;
}

size_t rths_proto_encode(const rths_msg *msg, uint8_t *buf, size_t cap) {
    return encode_as(msg, RTHS_PROTO_VERSION, buf, cap);
}

size_t rths_proto_encode_error_as(const rths_msg *msg, int version, uint8_t *buf, size_t cap) {
    if (!msg || msg->type != RTHS_MSG_ERROR || version < 1 || version > RTHS_PROTO_VERSION)
        return 0;
    return encode_as(msg, version, buf, cap);
}

/* ---- reader ---- */

typedef struct {
    const uint8_t *p;
    size_t n, pos;
    int bad;
    char *problem; /* the message's: what was wrong, when it can be said */
    size_t problem_cap;
} reader;

static const uint8_t *r_take(reader *r, size_t n) {
    if (r->bad || n > r->n - r->pos) {
        r->bad = 1;
        return NULL;
    }
    const uint8_t *q = r->p + r->pos;
    r->pos += n;
    return q;
}

static unsigned r_u8(reader *r) {
    const uint8_t *q = r_take(r, 1);
    return q ? q[0] : 0;
}

static unsigned r_u16(reader *r) {
    const uint8_t *q = r_take(r, 2);
    return q ? (unsigned)q[0] | (unsigned)q[1] << 8 : 0;
}

static uint32_t r_u32(reader *r) {
    const uint8_t *q = r_take(r, 4);
    uint32_t v = 0;
    if (q)
        for (int i = 3; i >= 0; i--)
            v = v << 8 | q[i];
    return v;
}

static uint64_t r_u64(reader *r) {
    const uint8_t *q = r_take(r, 8);
    uint64_t v = 0;
    if (q)
        for (int i = 7; i >= 0; i--)
            v = v << 8 | q[i];
    return v;
}

static double r_f64(reader *r) {
    uint64_t u = r_u64(r);
    double v;
    memcpy(&v, &u, sizeof v);
    if (!isfinite(v)) {
        r->bad = 1;
        return 0.0;
    }
    return v;
}

static void r_text(reader *r, char *out) {
    unsigned n = r_u8(r);
    out[0] = '\0';
    if (n > RTHS_PROTO_MAX_TEXT) {
        r->bad = 1;
        return;
    }
    const uint8_t *q = r_take(r, n);
    if (!q) return;
    if (memchr(q, 0, n)) { /* an embedded NUL would silently truncate the text */
        r->bad = 1;
        return;
    }
    memcpy(out, q, n);
    out[n] = '\0';
}

/* Field decoders, one per wire kind of the message list (protocol.h). */
static void dec_u8(reader *r, uint8_t *v) {
    *v = (uint8_t)r_u8(r);
}
static void dec_u16(reader *r, uint16_t *v) {
    *v = (uint16_t)r_u16(r);
}
static void dec_u32(reader *r, uint32_t *v) {
    *v = r_u32(r);
}
static void dec_u64(reader *r, uint64_t *v) {
    *v = r_u64(r);
}
static void dec_f64(reader *r, double *v) {
    *v = r_f64(r);
}
static void dec_text(reader *r, char (*v)[RTHS_PROTO_MAX_TEXT + 1]) {
    r_text(r, *v);
}
static void dec_fourier(reader *r, rths_proto_fourier *f) {
    for (int k = 0; k <= RTHS_PROTO_HARMONICS; k++)
        f->a[k] = r_f64(r);
    for (int k = 0; k <= RTHS_PROTO_HARMONICS; k++)
        f->b[k] = r_f64(r);
}
static void dec_latency_hist(reader *r, uint64_t (*h)[RTHS_PROTO_LATENCY_BINS]) {
    for (int i = 0; i < RTHS_PROTO_LATENCY_BINS; i++)
        (*h)[i] = r_u64(r);
}
/* A DoF count: 1..RTHS_PROTO_MAX_DOFS, anything else malformed and named. */
static unsigned r_dofs(reader *r) {
    unsigned n = r_u8(r);
    if (!r->bad && (n < 1 || n > RTHS_PROTO_MAX_DOFS)) {
        snprintf(r->problem, r->problem_cap, "%u interface DoFs; the protocol carries 1..%d", n,
                 RTHS_PROTO_MAX_DOFS);
        r->bad = 1;
    }
    return r->bad ? 0 : n;
}
static void dec_dof_values(reader *r, rths_proto_dof_values *v) {
    unsigned n = r_dofs(r);
    v->n = (int)n;
    for (unsigned d = 0; d < n; d++)
        v->v[d] = r_f64(r);
}
static void dec_target_dofs(reader *r, rths_proto_target *t) {
    unsigned n = r_dofs(r), h = r_u8(r);
    if (!r->bad && h > RTHS_PROTO_HARMONICS) {
        snprintf(r->problem, r->problem_cap, "%u harmonics; the protocol carries 0..%d", h,
                 RTHS_PROTO_HARMONICS);
        r->bad = 1;
    }
    if (r->bad) return;
    t->dofs = (int)n;
    t->harmonics = (int)h;
    for (unsigned d = 0; d < n; d++) {
        for (unsigned k = 0; k < h; k++)
            t->a[d * h + k] = r_f64(r);
        for (unsigned k = 0; k < h; k++)
            t->b[d * h + k] = r_f64(r);
    }
}
static void dec_period_dofs(reader *r, rths_proto_period *p) {
    unsigned n = r_dofs(r);
    p->interface_dofs = (int)n;
    for (unsigned d = 0; d < n; d++) {
        dec_fourier(r, d ? &p->phys_dof[d] : &p->phys);
        dec_fourier(r, d ? &p->num_dof[d] : &p->num);
        dec_fourier(r, d ? &p->force_dof[d] : &p->force);
    }
}
static void dec_output_dofs(reader *r, rths_proto_period *p) {
    p->output_dofs = 0;
    if (r->bad || r->pos == r->n) return; /* absent: none */
    unsigned m = r_u8(r);
    if (!r->bad && (m < 1 || m > RTHS_PROTO_MAX_OUTPUT_DOFS)) {
        snprintf(r->problem, r->problem_cap, "%u output DoFs; the protocol carries 1..%d", m,
                 RTHS_PROTO_MAX_OUTPUT_DOFS);
        r->bad = 1;
    }
    if (r->bad) return;
    p->output_dofs = (int)m;
    for (unsigned j = 0; j < m; j++)
        dec_fourier(r, &p->output_dof[j]);
}
static void dec_trace_batch(reader *r, rths_proto_trace *t) {
    unsigned n = r_dofs(r), c = r_u8(r);
    if (!r->bad && (c < 1 || c > RTHS_PROTO_MAX_TRACE_BATCH)) {
        snprintf(r->problem, r->problem_cap, "%u trace samples; a frame carries 1..%d", c,
                 RTHS_PROTO_MAX_TRACE_BATCH);
        r->bad = 1;
    }
    if (r->bad) return;
    t->dofs = (int)n;
    t->count = (int)c;
    for (unsigned i = 0; i < c; i++) {
        rths_proto_trace_sample *s = &t->s[i];
        s->time_s = r_f64(r);
        for (unsigned d = 0; d < n; d++) {
            double v[5];
            for (int j = 0; j < 5; j++)
                v[j] = r_f64(r);
            *(d ? &s->x_phys_dof_m[d] : &s->x_phys_m) = v[0];
            *(d ? &s->x_num_dof_m[d] : &s->x_num_m) = v[1];
            *(d ? &s->target_dof_m[d] : &s->target_m) = v[2];
            *(d ? &s->force_dof_n[d] : &s->force_n) = v[3];
            *(d ? &s->demand_dof[d] : &s->demand) = v[4];
        }
    }
}

#define DECODE_FIELD(kind, member, doc) dec_##kind(r, &m->u.member);
#define DECODE_CASE(name, code, direction, reply)                                                  \
    case code:                                                                                     \
        RTHS_PROTO_PAYLOAD_##name(DECODE_FIELD) break;

/* Returns RTHS_PROTO_OK, ETYPE or EPAYLOAD. Trailing bytes are a malformed payload: every type
 * has exactly one valid length for its contents. */
static int decode_payload(reader *r, rths_msg *m) {
    switch (m->type) {
        RTHS_PROTO_MESSAGES(DECODE_CASE)
    default:
        return RTHS_PROTO_ETYPE;
    }
    if (r->bad || r->pos != r->n || !payload_valid(m)) return RTHS_PROTO_EPAYLOAD;
    return RTHS_PROTO_OK;
}

/* version < 0: any version, ERROR frames only (their layout is the same in every version). */
static int decode_as(const uint8_t *buf, size_t len, rths_msg *msg, size_t *consumed, int version) {
    *consumed = 0;
    /* Judge each header byte as soon as it arrives, so garbage is refused without waiting for
     * (or trusting) a length. */
    if (len >= 1 && buf[0] != RTHS_PROTO_MAGIC0) return RTHS_PROTO_EMAGIC;
    if (len >= 2 && buf[1] != RTHS_PROTO_MAGIC1) return RTHS_PROTO_EMAGIC;
    if (len >= 3 && version >= 0 && buf[2] != version) return RTHS_PROTO_EVERSION;
    if (len >= 4 && version < 0 && buf[3] != RTHS_MSG_ERROR) return RTHS_PROTO_ETYPE;
    if (len < RTHS_PROTO_HEADER_SIZE) return RTHS_PROTO_INCOMPLETE;
    size_t plen = (size_t)buf[6] | (size_t)buf[7] << 8;
    if (plen > RTHS_PROTO_MAX_PAYLOAD) return RTHS_PROTO_EOVERSIZE;
    size_t total = RTHS_PROTO_HEADER_SIZE + plen + RTHS_PROTO_CRC_SIZE;
    if (len < total) return RTHS_PROTO_INCOMPLETE;
    const uint8_t *c = buf + RTHS_PROTO_HEADER_SIZE + plen;
    uint32_t want =
        (uint32_t)c[0] | (uint32_t)c[1] << 8 | (uint32_t)c[2] << 16 | (uint32_t)c[3] << 24;
    if (rths_crc32(buf, RTHS_PROTO_HEADER_SIZE + plen) != want) return RTHS_PROTO_ECRC;
    memset(msg, 0, sizeof *msg);
    msg->type = buf[3];
    msg->seq = (uint16_t)(buf[4] | buf[5] << 8);
    *consumed = total;
    reader r = {buf + RTHS_PROTO_HEADER_SIZE, plen, 0, 0, msg->problem, sizeof msg->problem};
    return decode_payload(&r, msg);
}

int rths_proto_decode(const uint8_t *buf, size_t len, rths_msg *msg, size_t *consumed) {
    return decode_as(buf, len, msg, consumed, RTHS_PROTO_VERSION);
}

int rths_proto_decode_error_any_version(const uint8_t *buf, size_t len, rths_msg *msg,
                                        size_t *consumed) {
    return decode_as(buf, len, msg, consumed, -1);
}

int rths_proto_frame_version(const uint8_t *buf, size_t len) {
    if (len < 3 || buf[0] != RTHS_PROTO_MAGIC0 || buf[1] != RTHS_PROTO_MAGIC1) return -1;
    return buf[2];
}

void rths_proto_version_message(char *out, size_t cap, int peer_version) {
    snprintf(out, cap, "peer speaks rths protocol version %d; this build speaks version %d",
             peer_version, RTHS_PROTO_VERSION);
}

void rths_proto_printable(const char *in, size_t max_chars, char *out, size_t cap) {
    if (!cap) return;
    size_t n = 0, i = 0;
    for (; in[i] && n < max_chars && n + 1 < cap; i++) {
        unsigned char ch = (unsigned char)in[i];
        out[n++] = ch >= 0x20 && ch < 0x7f ? (char)ch : '?';
    }
    if (in[i] && n + 4 <= cap) {
        memcpy(out + n, "...", 3);
        n += 3;
    }
    out[n] = '\0';
}

void rths_msg_init(rths_msg *msg, int type, uint16_t seq) {
    memset(msg, 0, sizeof *msg);
    msg->type = (uint8_t)type;
    msg->seq = seq;
}

void rths_msg_error(rths_msg *msg, uint16_t seq, int code, int request_type, const char *fmt, ...) {
    rths_msg_init(msg, RTHS_MSG_ERROR, seq);
    msg->u.error.code = (uint16_t)code;
    msg->u.error.request_type = (uint8_t)request_type;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg->u.error.message, sizeof msg->u.error.message, fmt, ap);
    va_end(ap);
}
