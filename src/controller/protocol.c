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
    case RTHS_MSG_HELLO:
        return "HELLO";
    case RTHS_MSG_ARM:
        return "ARM";
    case RTHS_MSG_DISARM:
        return "DISARM";
    case RTHS_MSG_SET_FORCING:
        return "SET_FORCING";
    case RTHS_MSG_SET_TARGET:
        return "SET_TARGET";
    case RTHS_MSG_GET_STATUS:
        return "GET_STATUS";
    case RTHS_MSG_GET_COEFFS:
        return "GET_COEFFS";
    case RTHS_MSG_SUBSCRIBE:
        return "SUBSCRIBE";
    case RTHS_MSG_RESET_FAULT:
        return "RESET_FAULT";
    case RTHS_MSG_PING:
        return "PING";
    case RTHS_MSG_HELLO_REPLY:
        return "HELLO_REPLY";
    case RTHS_MSG_ACK:
        return "ACK";
    case RTHS_MSG_STATUS:
        return "STATUS";
    case RTHS_MSG_PERIOD:
        return "PERIOD";
    case RTHS_MSG_TRACE:
        return "TRACE";
    case RTHS_MSG_ERROR:
        return "ERROR";
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

static void w_fourier(writer *w, const rths_proto_fourier *f) {
    for (int k = 0; k <= RTHS_PROTO_HARMONICS; k++)
        w_f64(w, f->a[k]);
    for (int k = 0; k <= RTHS_PROTO_HARMONICS; k++)
        w_f64(w, f->b[k]);
}

static void encode_payload(writer *w, const rths_msg *m) {
    switch (m->type) {
    case RTHS_MSG_HELLO:
        w_u16(w, m->u.hello.version);
        w_text(w, m->u.hello.name);
        break;
    case RTHS_MSG_ARM:
    case RTHS_MSG_DISARM:
    case RTHS_MSG_GET_STATUS:
    case RTHS_MSG_GET_COEFFS:
    case RTHS_MSG_RESET_FAULT:
    case RTHS_MSG_PING:
        break;
    case RTHS_MSG_SET_FORCING:
        w_f64(w, m->u.forcing.frequency_hz);
        w_f64(w, m->u.forcing.amplitude_n);
        break;
    case RTHS_MSG_SET_TARGET: {
        int h = m->u.target.harmonics;
        if (h < 0 || h > RTHS_PROTO_HARMONICS) {
            w->bad = 1;
            return;
        }
        w_u8(w, (unsigned)h);
        for (int k = 0; k < h; k++)
            w_f64(w, m->u.target.a[k]);
        for (int k = 0; k < h; k++)
            w_f64(w, m->u.target.b[k]);
        break;
    }
    case RTHS_MSG_SUBSCRIBE:
        if (m->u.subscribe.flags & ~(RTHS_SUBSCRIBE_PERIODS | RTHS_SUBSCRIBE_TRACES) ||
            m->u.subscribe.trace_decimation < 1) {
            w->bad = 1;
            return;
        }
        w_u8(w, m->u.subscribe.flags);
        w_u32(w, m->u.subscribe.trace_decimation);
        break;
    case RTHS_MSG_HELLO_REPLY:
        w_u16(w, m->u.hello_reply.version);
        w_u8(w, m->u.hello_reply.max_harmonics);
        w_f64(w, m->u.hello_reply.sample_period_s);
        w_f64(w, m->u.hello_reply.watchdog_s);
        w_f64(w, m->u.hello_reply.noise_level_m);
        w_text(w, m->u.hello_reply.name);
        break;
    case RTHS_MSG_ACK:
        w_u8(w, m->u.ack.acked_type);
        w_f64(w, m->u.ack.time_s);
        break;
    case RTHS_MSG_STATUS: {
        const rths_proto_status_msg *s = &m->u.status;
        w_f64(w, s->time_s);
        w_u8(w, s->flags);
        w_u8(w, s->fault);
        w_u8(w, s->last_disarm);
        w_f64(w, s->frequency_hz);
        w_f64(w, s->amplitude_n);
        w_u64(w, s->samples);
        w_u64(w, s->overruns);
        w_f64(w, s->worst_lateness_s);
        w_u64(w, s->periods_dropped);
        for (int i = 0; i < RTHS_PROTO_LATENCY_BINS; i++)
            w_u64(w, s->latency_hist[i]);
        break;
    }
    case RTHS_MSG_PERIOD: {
        const rths_proto_period *p = &m->u.period;
        w_u32(w, p->index);
        w_f64(w, p->frequency_hz);
        w_f64(w, p->start_time_s);
        w_f64(w, p->end_time_s);
        w_u32(w, p->samples);
        w_fourier(w, &p->phys);
        w_fourier(w, &p->num);
        w_fourier(w, &p->force);
        break;
    }
    case RTHS_MSG_TRACE: {
        int c = m->u.trace.count;
        if (c < 1 || c > RTHS_PROTO_MAX_TRACE_BATCH) {
            w->bad = 1;
            return;
        }
        w_u8(w, (unsigned)c);
        for (int i = 0; i < c; i++) {
            const rths_proto_trace_sample *s = &m->u.trace.s[i];
            w_f64(w, s->time_s);
            w_f64(w, s->x_phys_m);
            w_f64(w, s->x_num_m);
            w_f64(w, s->target_m);
            w_f64(w, s->force_n);
            w_f64(w, s->demand);
        }
        break;
    }
    case RTHS_MSG_ERROR:
        w_u16(w, m->u.error.code);
        w_u8(w, m->u.error.request_type);
        w_text(w, m->u.error.message);
        break;
    default:
        w->bad = 1;
    }
}

size_t rths_proto_encode(const rths_msg *msg, uint8_t *buf, size_t cap) {
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
    w_u8(&hw, RTHS_PROTO_VERSION);
    w_u8(&hw, msg->type);
    w_u16(&hw, msg->seq);
    w_u16(&hw, (unsigned)pw.n);
    size_t body = RTHS_PROTO_HEADER_SIZE + pw.n;
    writer cw = {buf + body, 0, RTHS_PROTO_CRC_SIZE, 0};
    w_u32(&cw, rths_crc32(buf, body));
    return body + RTHS_PROTO_CRC_SIZE;
}

/* ---- reader ---- */

typedef struct {
    const uint8_t *p;
    size_t n, pos;
    int bad;
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

static void r_fourier(reader *r, rths_proto_fourier *f) {
    for (int k = 0; k <= RTHS_PROTO_HARMONICS; k++)
        f->a[k] = r_f64(r);
    for (int k = 0; k <= RTHS_PROTO_HARMONICS; k++)
        f->b[k] = r_f64(r);
}

/* Returns RTHS_PROTO_OK, ETYPE or EPAYLOAD. Trailing bytes are a malformed payload: every type
 * has exactly one valid length for its contents. */
static int decode_payload(reader *r, rths_msg *m) {
    switch (m->type) {
    case RTHS_MSG_HELLO:
        m->u.hello.version = (uint16_t)r_u16(r);
        r_text(r, m->u.hello.name);
        break;
    case RTHS_MSG_ARM:
    case RTHS_MSG_DISARM:
    case RTHS_MSG_GET_STATUS:
    case RTHS_MSG_GET_COEFFS:
    case RTHS_MSG_RESET_FAULT:
    case RTHS_MSG_PING:
        break;
    case RTHS_MSG_SET_FORCING:
        m->u.forcing.frequency_hz = r_f64(r);
        m->u.forcing.amplitude_n = r_f64(r);
        break;
    case RTHS_MSG_SET_TARGET: {
        unsigned h = r_u8(r);
        if (h > RTHS_PROTO_HARMONICS) return RTHS_PROTO_EPAYLOAD;
        m->u.target.harmonics = (int)h;
        for (unsigned k = 0; k < h; k++)
            m->u.target.a[k] = r_f64(r);
        for (unsigned k = 0; k < h; k++)
            m->u.target.b[k] = r_f64(r);
        break;
    }
    case RTHS_MSG_SUBSCRIBE:
        m->u.subscribe.flags = (uint8_t)r_u8(r);
        m->u.subscribe.trace_decimation = r_u32(r);
        if (m->u.subscribe.flags & ~(RTHS_SUBSCRIBE_PERIODS | RTHS_SUBSCRIBE_TRACES) ||
            m->u.subscribe.trace_decimation < 1)
            return RTHS_PROTO_EPAYLOAD;
        break;
    case RTHS_MSG_HELLO_REPLY:
        m->u.hello_reply.version = (uint16_t)r_u16(r);
        m->u.hello_reply.max_harmonics = (uint8_t)r_u8(r);
        m->u.hello_reply.sample_period_s = r_f64(r);
        m->u.hello_reply.watchdog_s = r_f64(r);
        m->u.hello_reply.noise_level_m = r_f64(r);
        r_text(r, m->u.hello_reply.name);
        break;
    case RTHS_MSG_ACK:
        m->u.ack.acked_type = (uint8_t)r_u8(r);
        m->u.ack.time_s = r_f64(r);
        break;
    case RTHS_MSG_STATUS: {
        rths_proto_status_msg *s = &m->u.status;
        s->time_s = r_f64(r);
        s->flags = (uint8_t)r_u8(r);
        s->fault = (uint8_t)r_u8(r);
        s->last_disarm = (uint8_t)r_u8(r);
        s->frequency_hz = r_f64(r);
        s->amplitude_n = r_f64(r);
        s->samples = r_u64(r);
        s->overruns = r_u64(r);
        s->worst_lateness_s = r_f64(r);
        s->periods_dropped = r_u64(r);
        for (int i = 0; i < RTHS_PROTO_LATENCY_BINS; i++)
            s->latency_hist[i] = r_u64(r);
        break;
    }
    case RTHS_MSG_PERIOD: {
        rths_proto_period *p = &m->u.period;
        p->index = r_u32(r);
        p->frequency_hz = r_f64(r);
        p->start_time_s = r_f64(r);
        p->end_time_s = r_f64(r);
        p->samples = r_u32(r);
        r_fourier(r, &p->phys);
        r_fourier(r, &p->num);
        r_fourier(r, &p->force);
        break;
    }
    case RTHS_MSG_TRACE: {
        unsigned c = r_u8(r);
        if (c < 1 || c > RTHS_PROTO_MAX_TRACE_BATCH) return RTHS_PROTO_EPAYLOAD;
        m->u.trace.count = (int)c;
        for (unsigned i = 0; i < c; i++) {
            rths_proto_trace_sample *s = &m->u.trace.s[i];
            s->time_s = r_f64(r);
            s->x_phys_m = r_f64(r);
            s->x_num_m = r_f64(r);
            s->target_m = r_f64(r);
            s->force_n = r_f64(r);
            s->demand = r_f64(r);
        }
        break;
    }
    case RTHS_MSG_ERROR:
        m->u.error.code = (uint16_t)r_u16(r);
        m->u.error.request_type = (uint8_t)r_u8(r);
        r_text(r, m->u.error.message);
        break;
    default:
        return RTHS_PROTO_ETYPE;
    }
    if (r->bad || r->pos != r->n) return RTHS_PROTO_EPAYLOAD;
    return RTHS_PROTO_OK;
}

int rths_proto_decode(const uint8_t *buf, size_t len, rths_msg *msg, size_t *consumed) {
    *consumed = 0;
    /* Judge each header byte as soon as it arrives, so garbage is refused without waiting for
     * (or trusting) a length. */
    if (len >= 1 && buf[0] != RTHS_PROTO_MAGIC0) return RTHS_PROTO_EMAGIC;
    if (len >= 2 && buf[1] != RTHS_PROTO_MAGIC1) return RTHS_PROTO_EMAGIC;
    if (len >= 3 && buf[2] != RTHS_PROTO_VERSION) return RTHS_PROTO_EVERSION;
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
    reader r = {buf + RTHS_PROTO_HEADER_SIZE, plen, 0, 0};
    return decode_payload(&r, msg);
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
