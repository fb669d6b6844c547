/* Frame codec of the controller link: known-answer vectors (computed independently with Python's
 * struct + zlib.crc32, reproduced in docs/protocol.md), round trips of every message type, and
 * the documented answer to every kind of malformed input. */
#include "testlib.h"

#include "rths/protocol.h"

#include <dirent.h>
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

static void test_crc32_known_answer(void **state) {
    (void)state;
    /* The standard check value of CRC-32/ISO-HDLC. */
    assert_int_equal(rths_crc32((const uint8_t *)"123456789", 9), 0xCBF43926u);
    assert_int_equal(rths_crc32(NULL, 0), 0x00000000u);
}

/* Known-answer frames (docs/protocol.md, section 6), written by Python's struct and zlib.crc32;
 * the _v1 and _v2 ones are frames of those versions, as such a peer sends and reads them. */
static const uint8_t kat_ping[] = {0x52, 0x54, 0x03, 0x0a, 0x02, 0x01,
                                   0x00, 0x00, 0xc5, 0x2e, 0x54, 0xc2};
static const uint8_t kat_forcing[] = {0x52, 0x54, 0x03, 0x04, 0x07, 0x00, 0x10, 0x00, 0x71, 0x3d,
                                      0x0a, 0xd7, 0xa3, 0xf0, 0x2a, 0x40, 0x00, 0x00, 0x00, 0x00,
                                      0x00, 0x00, 0xf0, 0x3f, 0xd2, 0x8c, 0x50, 0x26};
static const uint8_t kat_target[] = {0x52, 0x54, 0x03, 0x05, 0x03, 0x00, 0x12, 0x00, 0x01, 0x01,
                                     0x2d, 0x43, 0x1c, 0xeb, 0xe2, 0x36, 0x1a, 0x3f, 0x2d, 0x43,
                                     0x1c, 0xeb, 0xe2, 0x36, 0x2a, 0xbf, 0x26, 0x49, 0x28, 0x45};
static const uint8_t kat_target2[] = {
    0x52, 0x54, 0x03, 0x05, 0x04, 0x00, 0x22, 0x00, 0x02, 0x01, 0x2d, 0x43, 0x1c, 0xeb, 0xe2, 0x36,
    0x1a, 0x3f, 0x2d, 0x43, 0x1c, 0xeb, 0xe2, 0x36, 0x2a, 0xbf, 0x61, 0x32, 0x55, 0x30, 0x2a, 0xa9,
    0x33, 0x3f, 0x2d, 0x43, 0x1c, 0xeb, 0xe2, 0x36, 0x0a, 0x3f, 0xd5, 0xe3, 0x55, 0xb8};
static const uint8_t kat_hello[] = {0x52, 0x54, 0x03, 0x01, 0x01, 0x00, 0x07, 0x00, 0x03, 0x00,
                                    0x04, 0x68, 0x6f, 0x73, 0x74, 0xd6, 0xf0, 0xe0, 0x66};
static const uint8_t kat_error[] = {0x52, 0x54, 0x03, 0xff, 0x09, 0x00, 0x06, 0x00, 0x06,
                                    0x00, 0x42, 0x02, 0x6e, 0x6f, 0x22, 0xd5, 0x81, 0x4b};
/* PERIOD seq 0, index 7, 21.819 Hz, 10.0 to 10.0458 s, 458 samples of which 3 late, 0 with a
 * clipped demand, 1 with a saturated sensor, n = 1, phys a[0] = 3.4e-4, every other coefficient
 * 0: its first 53 bytes (header to n) and its CRC (the frame is 345 bytes) */
static const uint8_t kat_period_head[] = {
    0x52, 0x54, 0x03, 0x84, 0x00, 0x00, 0x4d, 0x01, 0x07, 0x00, 0x00, 0x00, 0x8b, 0x6c,
    0xe7, 0xfb, 0xa9, 0xd1, 0x35, 0x40, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x24, 0x40,
    0x48, 0x50, 0xfc, 0x18, 0x73, 0x17, 0x24, 0x40, 0xca, 0x01, 0x00, 0x00, 0x03, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x01};
static const uint8_t kat_period_crc[] = {0xec, 0xb8, 0x7d, 0x2f};
static const uint8_t kat_hello_v2[] = {0x52, 0x54, 0x02, 0x01, 0x01, 0x00, 0x07, 0x00, 0x02, 0x00,
                                       0x04, 0x68, 0x6f, 0x73, 0x74, 0xe7, 0x22, 0x01, 0x1d};
static const uint8_t kat_error_v2[] = {0x52, 0x54, 0x02, 0xff, 0x09, 0x00, 0x06, 0x00, 0x06,
                                       0x00, 0x42, 0x02, 0x6e, 0x6f, 0x4d, 0x99, 0x24, 0xd0};
static const uint8_t kat_hello_v1[] = {0x52, 0x54, 0x01, 0x01, 0x01, 0x00, 0x07, 0x00, 0x01, 0x00,
                                       0x04, 0x68, 0x6f, 0x73, 0x74, 0xb4, 0x54, 0x23, 0x91};
static const uint8_t kat_error_v1[] = {0x52, 0x54, 0x01, 0xff, 0x09, 0x00, 0x06, 0x00, 0x06,
                                       0x00, 0x42, 0x02, 0x6e, 0x6f, 0xbd, 0x4b, 0xba, 0xa7};

static void check_encodes_to(const rths_msg *m, const uint8_t *want, size_t n) {
    uint8_t buf[RTHS_PROTO_MAX_FRAME];
    size_t len = rths_proto_encode(m, buf, sizeof buf);
    assert_int_equal(len, n);
    assert_memory_equal(buf, want, n);
}

static void test_known_answer_frames(void **state) {
    (void)state;
    rths_msg m;
    rths_msg_init(&m, RTHS_MSG_PING, 0x0102);
    check_encodes_to(&m, kat_ping, sizeof kat_ping);

    rths_msg_init(&m, RTHS_MSG_SET_FORCING, 7);
    m.u.forcing.frequency_hz = 13.47;
    m.u.forcing.amplitude_n = 1.0;
    check_encodes_to(&m, kat_forcing, sizeof kat_forcing);

    rths_msg_init(&m, RTHS_MSG_SET_TARGET, 3);
    m.u.target.harmonics = 1;
    m.u.target.a[0] = 1e-4;
    m.u.target.b[0] = -2e-4;
    check_encodes_to(&m, kat_target, sizeof kat_target);

    rths_msg_init(&m, RTHS_MSG_SET_TARGET, 4);
    m.u.target.dofs = 2;
    m.u.target.harmonics = 1;
    m.u.target.a[0] = 1e-4; /* DoF d's coefficient k at d * harmonics + k - 1 */
    m.u.target.b[0] = -2e-4;
    m.u.target.a[1] = 3e-4;
    m.u.target.b[1] = 5e-5;
    check_encodes_to(&m, kat_target2, sizeof kat_target2);

    rths_msg_init(&m, RTHS_MSG_HELLO, 1);
    m.u.hello.version = 3;
    strcpy(m.u.hello.name, "host");
    check_encodes_to(&m, kat_hello, sizeof kat_hello);

    rths_msg_error(&m, 9, RTHS_PROTO_ETYPE, 0x42, "%s", "no");
    check_encodes_to(&m, kat_error, sizeof kat_error);

    /* And the decoder reads the vectors back to the same values. */
    size_t used;
    assert_int_equal(rths_proto_decode(kat_forcing, sizeof kat_forcing, &m, &used), RTHS_PROTO_OK);
    assert_int_equal(used, sizeof kat_forcing);
    assert_int_equal(m.type, RTHS_MSG_SET_FORCING);
    assert_int_equal(m.seq, 7);
    assert_true(m.u.forcing.frequency_hz == 13.47 && m.u.forcing.amplitude_n == 1.0);
    assert_int_equal(rths_proto_decode(kat_target, sizeof kat_target, &m, &used), RTHS_PROTO_OK);
    assert_int_equal(m.u.target.harmonics, 1);
    assert_int_equal(m.u.target.dofs, 1);
    assert_true(m.u.target.a[0] == 1e-4 && m.u.target.b[0] == -2e-4);
    assert_int_equal(rths_proto_decode(kat_target2, sizeof kat_target2, &m, &used), RTHS_PROTO_OK);
    assert_int_equal(m.u.target.dofs, 2);
    assert_true(m.u.target.a[1] == 3e-4 && m.u.target.b[1] == 5e-5);
    assert_int_equal(rths_proto_decode(kat_hello, sizeof kat_hello, &m, &used), RTHS_PROTO_OK);
    assert_string_equal(m.u.hello.name, "host");
    assert_int_equal(rths_proto_decode(kat_error, sizeof kat_error, &m, &used), RTHS_PROTO_OK);
    assert_int_equal(m.u.error.code, RTHS_PROTO_ETYPE);
    assert_int_equal(m.u.error.request_type, 0x42);
    assert_string_equal(m.u.error.message, "no");

    /* PERIOD (version 3): the integrity counts after the samples */
    rths_msg_init(&m, RTHS_MSG_PERIOD, 0);
    m.u.period.index = 7;
    m.u.period.frequency_hz = 21.819;
    m.u.period.start_time_s = 10.0;
    m.u.period.end_time_s = 10.0458;
    m.u.period.samples = 458;
    m.u.period.late_samples = 3;
    m.u.period.saturated_sensor_samples = 1;
    m.u.period.phys.a[0] = 3.4e-4;
    uint8_t buf[RTHS_PROTO_MAX_FRAME];
    size_t len = rths_proto_encode(&m, buf, sizeof buf);
    assert_int_equal(len, 345);
    assert_memory_equal(buf, kat_period_head, sizeof kat_period_head);
    assert_memory_equal(buf + len - 4, kat_period_crc, 4);
    rths_msg back;
    assert_int_equal(rths_proto_decode(buf, len, &back, &used), RTHS_PROTO_OK);
    assert_int_equal(back.u.period.late_samples, 3);
    assert_int_equal(back.u.period.clipped_demand_samples, 0);
    assert_int_equal(back.u.period.saturated_sensor_samples, 1);
    /* a count above the period's samples is malformed, both ways */
    m.u.period.clipped_demand_samples = 459;
    assert_int_equal(rths_proto_encode(&m, buf, sizeof buf), 0);
}

/* A peer's text shown to an operator: printable ASCII, bounded (issue: a HELLO's client name
 * with a newline forged a console line, an escape reached the terminal). */
static void test_printable_text(void **state) {
    (void)state;
    char out[64];
    rths_proto_printable("host\nrths controller: t = 0 s: armed\x1b[2J", 40, out, sizeof out);
    assert_string_equal(out, "host?rths controller: t = 0 s: armed?[2J");
    rths_proto_printable("abcdefghij", 4, out, sizeof out);
    assert_string_equal(out, "abcd...");
    rths_proto_printable("\xc3\xa9t\xc3\xa9", 10, out, sizeof out);
    assert_string_equal(out, "??t??");
    rths_proto_printable("abcdefghij", 40, out, 5); /* the buffer bounds it too */
    assert_string_equal(out, "abcd");
}

static void fill_fourier(rths_proto_fourier *f, double base) {
    for (int k = 0; k <= RTHS_PROTO_HARMONICS; k++) {
        f->a[k] = base * (k + 1) - 0.125 * k;
        f->b[k] = k ? -base / (k + 3) : 0.0;
    }
}

/* One instance of every message type, with values that exercise sign, fractions and extremes. */
static int sample_messages(rths_msg *out) {
    int n = 0;
    rths_msg *m;
    m = &out[n++];
    rths_msg_init(m, RTHS_MSG_HELLO, 1);
    m->u.hello.version = RTHS_PROTO_VERSION;
    strcpy(m->u.hello.name, "rths host 0.1");
    static const int empty[] = {RTHS_MSG_ARM,        RTHS_MSG_DISARM,      RTHS_MSG_GET_STATUS,
                                RTHS_MSG_GET_COEFFS, RTHS_MSG_RESET_FAULT, RTHS_MSG_PING};
    for (size_t i = 0; i < sizeof empty / sizeof empty[0]; i++)
        rths_msg_init(&out[n++], empty[i], (uint16_t)(100 + i));
    m = &out[n++];
    rths_msg_init(m, RTHS_MSG_SET_FORCING, 65535);
    m->u.forcing.frequency_hz = 4.339;
    m->u.forcing.amplitude_n = 2.5e-3;
    for (int h = 0; h <= RTHS_PROTO_HARMONICS; h++) {
        for (int dofs = 1; dofs <= RTHS_PROTO_MAX_DOFS; dofs += RTHS_PROTO_MAX_DOFS - 1) {
            m = &out[n++];
            rths_msg_init(m, RTHS_MSG_SET_TARGET, (uint16_t)(200 + h));
            m->u.target.dofs = dofs;
            m->u.target.harmonics = h;
            for (int k = 0; k < h * dofs; k++) {
                m->u.target.a[k] = 1e-4 / (k + 1);
                m->u.target.b[k] = -DBL_MIN * (k + 1);
            }
        }
    }
    m = &out[n++];
    rths_msg_init(m, RTHS_MSG_SUBSCRIBE, 5);
    m->u.subscribe.flags = RTHS_SUBSCRIBE_PERIODS | RTHS_SUBSCRIBE_TRACES;
    m->u.subscribe.trace_decimation = 0xFFFFFFFFu;
    m = &out[n++];
    rths_msg_init(m, RTHS_MSG_HELLO_REPLY, 1);
    m->u.hello_reply.version = RTHS_PROTO_VERSION;
    m->u.hello_reply.max_harmonics = RTHS_PROTO_HARMONICS;
    m->u.hello_reply.interface_dofs = RTHS_PROTO_MAX_DOFS;
    m->u.hello_reply.sample_period_s = 1e-4;
    m->u.hello_reply.watchdog_s = 2.0;
    m->u.hello_reply.noise_level_m = 1e-7;
    memset(m->u.hello_reply.name, 'x', RTHS_PROTO_MAX_TEXT); /* the longest text allowed */
    m = &out[n++];
    rths_msg_init(m, RTHS_MSG_ACK, 2);
    m->u.ack.acked_type = RTHS_MSG_SET_TARGET;
    m->u.ack.time_s = 123.4567;
    m = &out[n++];
    rths_msg_init(m, RTHS_MSG_STATUS, 3);
    m->u.status.time_s = 1e5;
    m->u.status.flags = RTHS_STATUS_ARMED | RTHS_STATUS_RT_PINNED;
    m->u.status.fault = 6;
    m->u.status.last_disarm = RTHS_DISARM_WATCHDOG;
    m->u.status.frequency_hz = 13.47;
    m->u.status.amplitude_n = 1.0;
    m->u.status.samples = UINT64_MAX;
    m->u.status.overruns = 17;
    m->u.status.worst_lateness_s = 3.2e-3;
    m->u.status.periods_dropped = 2;
    for (int i = 0; i < RTHS_PROTO_LATENCY_BINS; i++)
        m->u.status.latency_hist[i] = (uint64_t)1 << (3 * i);
    m->u.status.demand_v.n = 2;
    m->u.status.demand_v.v[0] = -1.25;
    m->u.status.demand_v.v[1] = 9.5;
    strcpy(m->u.status.fault_detail, "watchdog: the host was silent for 2.1 s, beyond "
                                     "server.watchdog_s = 2 s");
    m = &out[n++];
    rths_msg_init(m, RTHS_MSG_PERIOD, 0);
    m->u.period.index = 4000000000u;
    m->u.period.frequency_hz = 21.819;
    m->u.period.start_time_s = 10.0;
    m->u.period.end_time_s = 10.0458;
    m->u.period.samples = 458;
    m->u.period.late_samples = 458;
    m->u.period.clipped_demand_samples = 12;
    m->u.period.saturated_sensor_samples = 1;
    fill_fourier(&m->u.period.phys, 3.42e-4);
    fill_fourier(&m->u.period.num, -3.40e-4);
    fill_fourier(&m->u.period.force, 0.75);
    m->u.period.interface_dofs = 1;
    for (int dofs = 2; dofs <= RTHS_PROTO_MAX_DOFS; dofs++) {
        m = &out[n++];
        *m = out[n - 2];
        m->u.period.interface_dofs = dofs;
        fill_fourier(&m->u.period.phys_dof[dofs - 1], 1e-4 * dofs);
        fill_fourier(&m->u.period.num_dof[dofs - 1], -2e-4 * dofs);
        fill_fourier(&m->u.period.force_dof[dofs - 1], 0.5 * dofs);
    }
    m = &out[n++];
    rths_msg_init(m, RTHS_MSG_TRACE, 0);
    m->u.trace.count = RTHS_PROTO_MAX_TRACE_BATCH;
    m->u.trace.dofs = 1;
    for (int i = 0; i < RTHS_PROTO_MAX_TRACE_BATCH; i++) {
        m->u.trace.s[i] = (rths_proto_trace_sample){.time_s = i * 1e-3,
                                                    .x_phys_m = 1e-4 * i,
                                                    .x_num_m = -2e-4 * i,
                                                    .target_m = 3e-4,
                                                    .force_n = -0.5 * i,
                                                    .demand = 0.01 * i};
    }
    /* the largest message: a full batch of the most interface DoFs */
    m = &out[n++];
    *m = out[n - 2];
    m->u.trace.dofs = RTHS_PROTO_MAX_DOFS;
    for (int i = 0; i < RTHS_PROTO_MAX_TRACE_BATCH; i++)
        for (int d = 1; d < RTHS_PROTO_MAX_DOFS; d++) {
            rths_proto_trace_sample *x = &m->u.trace.s[i];
            x->x_phys_dof_m[d] = 1e-5 * d - i;
            x->x_num_dof_m[d] = -1e-5 * d;
            x->target_dof_m[d] = 2e-5 * d;
            x->force_dof_n[d] = 0.1 * d * i;
            x->demand_dof[d] = -0.02 * d;
        }
    m = &out[n++];
    rths_msg_error(m, 77, RTHS_PROTO_EBUSY, RTHS_MSG_ARM, "controller armed by %s", "10.0.0.1");
    return n;
}

/* output.dofs' optional last block of a PERIOD: absent without output DoFs (the frame as
 * before, 57 + 288 n bytes), else u8 m and m fourier blocks (1 + 96 m bytes more); the largest
 * PERIOD (4 interface DoFs, 16 output DoFs) fits the payload bound; a count of 0 or 17 in the
 * block is malformed and named. */
static void test_period_output_dofs(void **state) {
    (void)state;
    rths_msg m, back;
    rths_msg_init(&m, RTHS_MSG_PERIOD, 0);
    rths_proto_period *p = &m.u.period;
    p->index = 3, p->frequency_hz = 13.25, p->samples = 755;
    fill_fourier(&p->phys, 1e-4);
    p->interface_dofs = 1;
    uint8_t buf[RTHS_PROTO_MAX_FRAME];
    size_t used = 0;
    assert_int_equal(rths_proto_encode(&m, buf, sizeof buf), 57 + 288);
    p->interface_dofs = 4;
    for (int d = 1; d < 4; d++)
        fill_fourier(&p->phys_dof[d], 1e-3 * d);
    p->output_dofs = RTHS_PROTO_MAX_OUTPUT_DOFS;
    for (int j = 0; j < p->output_dofs; j++)
        fill_fourier(&p->output_dof[j], -2e-5 * (j + 1));
    size_t len = rths_proto_encode(&m, buf, sizeof buf);
    assert_int_equal(len, 57 + 288 * 4 + 1 + 96 * RTHS_PROTO_MAX_OUTPUT_DOFS);
    assert_int_equal(len, 2746);
    assert_int_equal(rths_proto_decode(buf, len, &back, &used), RTHS_PROTO_OK);
    assert_memory_equal(&back, &m, sizeof m);
    /* one output DoF on one interface DoF: then its count byte set to 0 (CRC fixed) */
    rths_msg_init(&m, RTHS_MSG_PERIOD, 0);
    p->interface_dofs = 1, p->samples = 10;
    p->output_dofs = 1;
    fill_fourier(&p->output_dof[0], 5e-5);
    len = rths_proto_encode(&m, buf, sizeof buf);
    assert_int_equal(len, 57 + 288 + 1 + 96);
    assert_int_equal(rths_proto_decode(buf, len, &back, &used), RTHS_PROTO_OK);
    assert_int_equal(back.u.period.output_dofs, 1);
    assert_memory_equal(&back.u.period.output_dof[0], &p->output_dof[0], sizeof p->output_dof[0]);
    for (int count = 0; count <= 17; count += 17) {
        size_t at = len - RTHS_PROTO_CRC_SIZE - 96 - 1;
        buf[at] = (uint8_t)count;
        uint32_t crc = rths_crc32(buf, len - RTHS_PROTO_CRC_SIZE);
        for (int b = 0; b < 4; b++)
            buf[len - RTHS_PROTO_CRC_SIZE + (size_t)b] = (uint8_t)(crc >> (8 * b));
        assert_int_equal(rths_proto_decode(buf, len, &back, &used), RTHS_PROTO_EPAYLOAD);
        assert_non_null(strstr(back.problem, "output DoFs; the protocol carries 1..16"));
    }
    /* more output DoFs than the protocol carries: nothing is encoded */
    p->output_dofs = RTHS_PROTO_MAX_OUTPUT_DOFS + 1;
    assert_int_equal(rths_proto_encode(&m, buf, sizeof buf), 0);
}

static void test_round_trip_every_type(void **state) {
    (void)state;
    rths_msg msgs[40];
    int n = sample_messages(msgs);
    int seen[256] = {0};
    for (int i = 0; i < n; i++) {
        uint8_t buf[RTHS_PROTO_MAX_FRAME];
        size_t len = rths_proto_encode(&msgs[i], buf, sizeof buf);
        assert_true(len >= RTHS_PROTO_HEADER_SIZE + RTHS_PROTO_CRC_SIZE);
        assert_true(len <= RTHS_PROTO_MAX_FRAME);
        rths_msg back;
        size_t used = 0;
        assert_int_equal(rths_proto_decode(buf, len, &back, &used), RTHS_PROTO_OK);
        assert_int_equal(used, len);
        assert_memory_equal(&back, &msgs[i], sizeof back);
        seen[msgs[i].type] = 1;
        /* Encoding exactly into a buffer of the frame's size works; one byte less does not. */
        uint8_t tight[RTHS_PROTO_MAX_FRAME];
        assert_int_equal(rths_proto_encode(&msgs[i], tight, len), len);
        assert_int_equal(rths_proto_encode(&msgs[i], tight, len - 1), 0);
    }
    static const int all[] = {
        RTHS_MSG_HELLO,       RTHS_MSG_ARM,        RTHS_MSG_DISARM,      RTHS_MSG_SET_FORCING,
        RTHS_MSG_SET_TARGET,  RTHS_MSG_GET_STATUS, RTHS_MSG_GET_COEFFS,  RTHS_MSG_SUBSCRIBE,
        RTHS_MSG_RESET_FAULT, RTHS_MSG_PING,       RTHS_MSG_HELLO_REPLY, RTHS_MSG_ACK,
        RTHS_MSG_STATUS,      RTHS_MSG_PERIOD,     RTHS_MSG_TRACE,       RTHS_MSG_ERROR};
    for (size_t i = 0; i < sizeof all / sizeof all[0]; i++)
        assert_true(seen[all[i]]);
}

static void test_truncated_frames_are_incomplete(void **state) {
    (void)state;
    rths_msg msgs[40];
    int n = sample_messages(msgs);
    for (int i = 0; i < n; i++) {
        uint8_t buf[RTHS_PROTO_MAX_FRAME];
        size_t len = rths_proto_encode(&msgs[i], buf, sizeof buf);
        for (size_t cut = 0; cut < len; cut++) {
            rths_msg back;
            size_t used = 99;
            assert_int_equal(rths_proto_decode(buf, cut, &back, &used), RTHS_PROTO_INCOMPLETE);
            assert_int_equal(used, 0);
        }
    }
}

static void test_back_to_back_frames(void **state) {
    (void)state;
    uint8_t buf[2 * RTHS_PROTO_MAX_FRAME];
    memcpy(buf, kat_forcing, sizeof kat_forcing);
    memcpy(buf + sizeof kat_forcing, kat_ping, sizeof kat_ping);
    rths_msg m;
    size_t used;
    assert_int_equal(rths_proto_decode(buf, sizeof kat_forcing + sizeof kat_ping, &m, &used),
                     RTHS_PROTO_OK);
    assert_int_equal(used, sizeof kat_forcing);
    assert_int_equal(m.type, RTHS_MSG_SET_FORCING);
    assert_int_equal(rths_proto_decode(buf + used, sizeof kat_ping, &m, &used), RTHS_PROTO_OK);
    assert_int_equal(m.type, RTHS_MSG_PING);
    assert_int_equal(m.seq, 0x0102);
}

/* Writes a well-framed frame (good CRC) of arbitrary type and payload. */
static size_t raw_frame(uint8_t *buf, int type, uint16_t seq, const uint8_t *payload, size_t n) {
    buf[0] = RTHS_PROTO_MAGIC0;
    buf[1] = RTHS_PROTO_MAGIC1;
    buf[2] = RTHS_PROTO_VERSION;
    buf[3] = (uint8_t)type;
    buf[4] = (uint8_t)seq;
    buf[5] = (uint8_t)(seq >> 8);
    buf[6] = (uint8_t)n;
    buf[7] = (uint8_t)(n >> 8);
    if (n) memcpy(buf + 8, payload, n);
    uint32_t c = rths_crc32(buf, 8 + n);
    for (int i = 0; i < 4; i++)
        buf[8 + n + (size_t)i] = (uint8_t)(c >> (8 * i));
    return 8 + n + 4;
}

static void test_header_errors_detected_early(void **state) {
    (void)state;
    rths_msg m;
    size_t used = 99;
    const uint8_t garbage[] = {'G', 'E', 'T', ' ', '/'};
    assert_int_equal(rths_proto_decode(garbage, 1, &m, &used), RTHS_PROTO_EMAGIC);
    assert_int_equal(used, 0);
    const uint8_t half_magic[] = {0x52, 0x00};
    assert_int_equal(rths_proto_decode(half_magic, 2, &m, &used), RTHS_PROTO_EMAGIC);
    const uint8_t v1[] = {0x52, 0x54, 0x01};
    assert_int_equal(rths_proto_decode(v1, 3, &m, &used), RTHS_PROTO_EVERSION);
    const uint8_t v2[] = {0x52, 0x54, 0x02};
    assert_int_equal(rths_proto_decode(v2, 3, &m, &used), RTHS_PROTO_EVERSION);
    const uint8_t v4[] = {0x52, 0x54, 0x04};
    assert_int_equal(rths_proto_decode(v4, 3, &m, &used), RTHS_PROTO_EVERSION);
    const uint8_t v0[] = {0x52, 0x54, 0x00, 0x0a, 0, 0, 0, 0};
    assert_int_equal(rths_proto_decode(v0, sizeof v0, &m, &used), RTHS_PROTO_EVERSION);
    /* Payload length 4097: refused from the header alone, before any payload arrives. */
    const uint8_t big[] = {0x52, 0x54, 0x03, 0x0a, 0, 0, 0x01, 0x10};
    assert_int_equal(rths_proto_decode(big, sizeof big, &m, &used), RTHS_PROTO_EOVERSIZE);
    const uint8_t huge[] = {0x52, 0x54, 0x03, 0x0a, 0, 0, 0xff, 0xff};
    assert_int_equal(rths_proto_decode(huge, sizeof huge, &m, &used), RTHS_PROTO_EOVERSIZE);
    assert_true(rths_proto_status_is_fatal(RTHS_PROTO_EMAGIC));
    assert_true(rths_proto_status_is_fatal(RTHS_PROTO_EVERSION));
    assert_true(rths_proto_status_is_fatal(RTHS_PROTO_EOVERSIZE));
    assert_true(rths_proto_status_is_fatal(RTHS_PROTO_ECRC));
    assert_false(rths_proto_status_is_fatal(RTHS_PROTO_ETYPE));
    assert_false(rths_proto_status_is_fatal(RTHS_PROTO_EPAYLOAD));
}

static void test_maximum_payload_is_accepted_by_framing(void **state) {
    (void)state;
    static uint8_t payload[RTHS_PROTO_MAX_PAYLOAD];
    static uint8_t buf[RTHS_PROTO_MAX_FRAME];
    size_t len = raw_frame(buf, 0x7E, 11, payload, sizeof payload);
    rths_msg m;
    size_t used;
    /* Framing accepts the full 4096 bytes; the (unknown) type is what gets refused. */
    assert_int_equal(rths_proto_decode(buf, len, &m, &used), RTHS_PROTO_ETYPE);
    assert_int_equal(used, len);
    assert_int_equal(m.seq, 11);
    assert_int_equal(m.type, 0x7E);
}

static void test_every_bit_flip_is_caught(void **state) {
    (void)state;
    uint8_t buf[64];
    memcpy(buf, kat_forcing, sizeof kat_forcing);
    for (size_t byte = 0; byte < sizeof kat_forcing; byte++) {
        for (int bit = 0; bit < 8; bit++) {
            buf[byte] ^= (uint8_t)(1u << bit);
            rths_msg m;
            size_t used;
            int st = rths_proto_decode(buf, sizeof kat_forcing, &m, &used);
            buf[byte] ^= (uint8_t)(1u << bit);
            assert_int_not_equal(st, RTHS_PROTO_OK);
            if (byte >= RTHS_PROTO_HEADER_SIZE || byte == 3 || byte == 4 || byte == 5)
                assert_int_equal(st, RTHS_PROTO_ECRC); /* type, seq, payload, CRC bytes */
            if (byte >= 6 && byte < 8 && st != RTHS_PROTO_ECRC)
                /* a corrupted length either outruns the buffer or the limit */
                assert_true(st == RTHS_PROTO_INCOMPLETE || st == RTHS_PROTO_EOVERSIZE);
        }
    }
}

static void test_malformed_payloads(void **state) {
    (void)state;
    uint8_t buf[RTHS_PROTO_MAX_FRAME];
    rths_msg m;
    size_t used, len;
    /* A command that takes no payload, given one byte. */
    const uint8_t one[] = {0};
    len = raw_frame(buf, RTHS_MSG_ARM, 5, one, 1);
    assert_int_equal(rths_proto_decode(buf, len, &m, &used), RTHS_PROTO_EPAYLOAD);
    assert_int_equal(used, len); /* well-framed: the receiver skips it and stays in sync */
    assert_int_equal(m.type, RTHS_MSG_ARM);
    assert_int_equal(m.seq, 5);
    /* SET_FORCING one byte short. */
    memcpy(buf, kat_forcing, sizeof kat_forcing);
    len = raw_frame(buf, RTHS_MSG_SET_FORCING, 7, kat_forcing + 8, 15);
    assert_int_equal(rths_proto_decode(buf, len, &m, &used), RTHS_PROTO_EPAYLOAD);
    /* SET_TARGET with 6 harmonics (above the maximum of 5), named. */
    uint8_t tgt[2 + 12 * 8] = {1, 6};
    len = raw_frame(buf, RTHS_MSG_SET_TARGET, 1, tgt, sizeof tgt);
    assert_int_equal(rths_proto_decode(buf, len, &m, &used), RTHS_PROTO_EPAYLOAD);
    assert_string_equal(m.problem, "6 harmonics; the protocol carries 0..5");
    /* SET_TARGET declaring 2 harmonics but carrying 1; two DoFs but carrying one. */
    uint8_t tgt2[2 + 2 * 8] = {1, 2};
    len = raw_frame(buf, RTHS_MSG_SET_TARGET, 1, tgt2, sizeof tgt2);
    assert_int_equal(rths_proto_decode(buf, len, &m, &used), RTHS_PROTO_EPAYLOAD);
    uint8_t tgt3[2 + 2 * 8] = {2, 1};
    len = raw_frame(buf, RTHS_MSG_SET_TARGET, 1, tgt3, sizeof tgt3);
    assert_int_equal(rths_proto_decode(buf, len, &m, &used), RTHS_PROTO_EPAYLOAD);
    /* A NaN frequency (quiet NaN, little-endian) and an infinite amplitude. */
    uint8_t nanf[16] = {0, 0, 0, 0, 0, 0, 0xf8, 0x7f, 0, 0, 0, 0, 0, 0, 0xf0, 0x3f};
    len = raw_frame(buf, RTHS_MSG_SET_FORCING, 1, nanf, sizeof nanf);
    assert_int_equal(rths_proto_decode(buf, len, &m, &used), RTHS_PROTO_EPAYLOAD);
    uint8_t inff[16] = {0, 0, 0, 0, 0, 0, 0xf0, 0x3f, 0, 0, 0, 0, 0, 0, 0xf0, 0x7f};
    len = raw_frame(buf, RTHS_MSG_SET_FORCING, 1, inff, sizeof inff);
    assert_int_equal(rths_proto_decode(buf, len, &m, &used), RTHS_PROTO_EPAYLOAD);
    /* Text length running past the payload, and text with an embedded NUL. */
    const uint8_t longname[] = {1, 0, 9, 'a', 'b'};
    len = raw_frame(buf, RTHS_MSG_HELLO, 1, longname, sizeof longname);
    assert_int_equal(rths_proto_decode(buf, len, &m, &used), RTHS_PROTO_EPAYLOAD);
    const uint8_t nulname[] = {1, 0, 3, 'a', 0, 'b'};
    len = raw_frame(buf, RTHS_MSG_HELLO, 1, nulname, sizeof nulname);
    assert_int_equal(rths_proto_decode(buf, len, &m, &used), RTHS_PROTO_EPAYLOAD);
    /* SUBSCRIBE with decimation 0 and with an undefined flag bit. */
    const uint8_t dec0[] = {1, 0, 0, 0, 0};
    len = raw_frame(buf, RTHS_MSG_SUBSCRIBE, 1, dec0, sizeof dec0);
    assert_int_equal(rths_proto_decode(buf, len, &m, &used), RTHS_PROTO_EPAYLOAD);
    const uint8_t badflag[] = {4, 1, 0, 0, 0};
    len = raw_frame(buf, RTHS_MSG_SUBSCRIBE, 1, badflag, sizeof badflag);
    assert_int_equal(rths_proto_decode(buf, len, &m, &used), RTHS_PROTO_EPAYLOAD);
    /* TRACE with zero samples. */
    const uint8_t tr0[] = {1, 0};
    len = raw_frame(buf, RTHS_MSG_TRACE, 1, tr0, sizeof tr0);
    assert_int_equal(rths_proto_decode(buf, len, &m, &used), RTHS_PROTO_EPAYLOAD);
    /* Unknown types. */
    len = raw_frame(buf, 0x00, 1, NULL, 0);
    assert_int_equal(rths_proto_decode(buf, len, &m, &used), RTHS_PROTO_ETYPE);
    len = raw_frame(buf, 0x80, 1, NULL, 0);
    assert_int_equal(rths_proto_decode(buf, len, &m, &used), RTHS_PROTO_ETYPE);
}

static void test_encoder_refuses_invalid_messages(void **state) {
    (void)state;
    uint8_t buf[RTHS_PROTO_MAX_FRAME];
    rths_msg m;
    rths_msg_init(&m, RTHS_MSG_SET_FORCING, 1);
    m.u.forcing.frequency_hz = NAN;
    assert_int_equal(rths_proto_encode(&m, buf, sizeof buf), 0);
    rths_msg_init(&m, RTHS_MSG_SET_TARGET, 1);
    m.u.target.harmonics = RTHS_PROTO_HARMONICS + 1;
    assert_int_equal(rths_proto_encode(&m, buf, sizeof buf), 0);
    m.u.target.harmonics = -1;
    assert_int_equal(rths_proto_encode(&m, buf, sizeof buf), 0);
    rths_msg_init(&m, RTHS_MSG_HELLO, 1);
    memset(m.u.hello.name, 'y', sizeof m.u.hello.name); /* no terminator within the limit */
    assert_int_equal(rths_proto_encode(&m, buf, sizeof buf), 0);
    rths_msg_init(&m, 0x33, 1);
    assert_int_equal(rths_proto_encode(&m, buf, sizeof buf), 0);
    rths_msg_init(&m, RTHS_MSG_TRACE, 1);
    assert_int_equal(rths_proto_encode(&m, buf, sizeof buf), 0); /* count 0 */
    /* more interface DoFs than a frame carries, in every vector message */
    rths_msg_init(&m, RTHS_MSG_SET_TARGET, 1);
    m.u.target.dofs = RTHS_PROTO_MAX_DOFS + 1;
    assert_int_equal(rths_proto_encode(&m, buf, sizeof buf), 0);
    rths_msg_init(&m, RTHS_MSG_PERIOD, 1);
    m.u.period.interface_dofs = RTHS_PROTO_MAX_DOFS + 1;
    assert_int_equal(rths_proto_encode(&m, buf, sizeof buf), 0);
    rths_msg_init(&m, RTHS_MSG_STATUS, 1);
    m.u.status.demand_v.n = -1;
    assert_int_equal(rths_proto_encode(&m, buf, sizeof buf), 0);
    rths_msg_init(&m, RTHS_MSG_HELLO_REPLY, 1);
    m.u.hello_reply.sample_period_s = 1e-4;
    assert_int_equal(rths_proto_encode(&m, buf, sizeof buf), 0); /* interface DoFs 0 */
    rths_msg_init(&m, RTHS_MSG_PING, 1);
    assert_int_equal(rths_proto_encode(&m, buf, 11), 0); /* a 12-byte frame */
}

/* Every vector message refuses an interface DoF count of 0 or above RTHS_PROTO_MAX_DOFS as a
 * malformed payload naming the count (the frame is skipped; the connection stays in step). */
static void test_dof_counts_are_bounded(void **state) {
    (void)state;
    uint8_t buf[RTHS_PROTO_MAX_FRAME], payload[RTHS_PROTO_MAX_PAYLOAD];
    rths_msg m;
    size_t used, len;
    const unsigned bad[] = {0, RTHS_PROTO_MAX_DOFS + 1, 255};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        char want[96];
        snprintf(want, sizeof want, "%u interface DoFs; the protocol carries 1..%d", bad[i],
                 RTHS_PROTO_MAX_DOFS);
        /* SET_TARGET: the count first; sized as if the count were true, with H = 1 */
        memset(payload, 0, sizeof payload);
        payload[0] = (uint8_t)bad[i];
        payload[1] = 1;
        len = raw_frame(buf, RTHS_MSG_SET_TARGET, 3, payload, 2 + 16 * bad[i]);
        assert_int_equal(rths_proto_decode(buf, len, &m, &used), RTHS_PROTO_EPAYLOAD);
        assert_int_equal(used, len);
        assert_string_equal(m.problem, want);
        /* PERIOD: 44 bytes of scalars (version 3: the integrity counts), then the count */
        memset(payload, 0, sizeof payload);
        payload[44] = (uint8_t)bad[i];
        len = raw_frame(buf, RTHS_MSG_PERIOD, 0, payload, 45 + 288 * (bad[i] < 5 ? bad[i] : 5));
        assert_int_equal(rths_proto_decode(buf, len, &m, &used), RTHS_PROTO_EPAYLOAD);
        assert_string_equal(m.problem, want);
        /* TRACE: the count, then one sample */
        memset(payload, 0, sizeof payload);
        payload[0] = (uint8_t)bad[i];
        payload[1] = 1;
        len = raw_frame(buf, RTHS_MSG_TRACE, 0, payload, 2 + 8 + 40 * (bad[i] < 5 ? bad[i] : 5));
        assert_int_equal(rths_proto_decode(buf, len, &m, &used), RTHS_PROTO_EPAYLOAD);
        assert_string_equal(m.problem, want);
    }
    /* HELLO_REPLY announcing 0 interface DoFs */
    rths_msg_init(&m, RTHS_MSG_HELLO_REPLY, 1);
    m.u.hello_reply.interface_dofs = 1;
    len = rths_proto_encode(&m, buf, sizeof buf);
    assert_true(len > 0);
    memcpy(payload, buf + 8, len - 12);
    payload[3] = 0; /* u16 version, u8 max harmonics, then the count */
    len = raw_frame(buf, RTHS_MSG_HELLO_REPLY, 1, payload, len - 12);
    assert_int_equal(rths_proto_decode(buf, len, &m, &used), RTHS_PROTO_EPAYLOAD);
}

/* A version-1 peer: its frames are refused from byte 2 alone, and the version is named; an ERROR
 * frame (the same layout in both versions) can be written in version-1 framing and read from it,
 * so either end can tell the other why the link is refused. */
static void test_version_one_peer(void **state) {
    (void)state;
    rths_msg m;
    size_t used = 99;
    assert_int_equal(rths_proto_decode(kat_hello_v1, sizeof kat_hello_v1, &m, &used),
                     RTHS_PROTO_EVERSION);
    assert_int_equal(used, 0);
    assert_int_equal(rths_proto_frame_version(kat_hello_v1, sizeof kat_hello_v1), 1);
    assert_int_equal(rths_proto_frame_version(kat_hello_v1, 2), -1);
    assert_int_equal(rths_proto_frame_version((const uint8_t *)"GET", 3), -1);
    char msg[RTHS_PROTO_MAX_TEXT + 1];
    rths_proto_version_message(msg, sizeof msg, 1);
    assert_string_equal(msg, "peer speaks rths protocol version 1; this build speaks version 3");
    assert_int_equal(rths_proto_decode(kat_hello_v2, sizeof kat_hello_v2, &m, &used),
                     RTHS_PROTO_EVERSION);
    assert_int_equal(rths_proto_frame_version(kat_hello_v2, sizeof kat_hello_v2), 2);

    uint8_t buf[RTHS_PROTO_MAX_FRAME];
    rths_msg_error(&m, 9, RTHS_PROTO_ETYPE, 0x42, "%s", "no");
    assert_int_equal(rths_proto_encode_error_as(&m, 1, buf, sizeof buf), sizeof kat_error_v1);
    assert_memory_equal(buf, kat_error_v1, sizeof kat_error_v1);
    assert_int_equal(rths_proto_encode_error_as(&m, 2, buf, sizeof buf), sizeof kat_error_v2);
    assert_memory_equal(buf, kat_error_v2, sizeof kat_error_v2);
    assert_int_equal(rths_proto_encode_error_as(&m, 3, buf, sizeof buf), sizeof kat_error);
    assert_memory_equal(buf, kat_error, sizeof kat_error);
    assert_int_equal(rths_proto_encode_error_as(&m, 4, buf, sizeof buf), 0);
    assert_int_equal(rths_proto_encode_error_as(&m, 0, buf, sizeof buf), 0);
    rths_msg_init(&m, RTHS_MSG_PING, 1); /* only ERROR frames cross versions */
    assert_int_equal(rths_proto_encode_error_as(&m, 1, buf, sizeof buf), 0);

    assert_int_equal(
        rths_proto_decode_error_any_version(kat_error_v1, sizeof kat_error_v1, &m, &used),
        RTHS_PROTO_OK);
    assert_int_equal(used, sizeof kat_error_v1);
    assert_int_equal(m.u.error.code, RTHS_PROTO_ETYPE);
    assert_string_equal(m.u.error.message, "no");
    assert_int_equal(
        rths_proto_decode_error_any_version(kat_hello_v1, sizeof kat_hello_v1, &m, &used),
        RTHS_PROTO_ETYPE);
    assert_int_equal(rths_proto_decode_error_any_version(kat_error_v1, 10, &m, &used),
                     RTHS_PROTO_INCOMPLETE);
}

/* Frame sizes of the messages that grew, version 1 against version 2 (docs/protocol.md, section
 * 1): version 1's from its layout (PERIOD 8 + 32 + 3 x 96 + 4, SET_TARGET 8 + 1 + H x 16 + 4,
 * TRACE 8 + 1 + 16 x 48 + 4), version 2's from the encoder, checked against the layout. */
static void test_frame_sizes(void **state) {
    (void)state;
    uint8_t buf[RTHS_PROTO_MAX_FRAME];
    rths_msg m;
    const size_t fourier = 12 * 8, frame = RTHS_PROTO_HEADER_SIZE + RTHS_PROTO_CRC_SIZE;
    for (int n = 1; n <= RTHS_PROTO_MAX_DOFS; n++) {
        rths_msg_init(&m, RTHS_MSG_PERIOD, 0);
        m.u.period.interface_dofs = n;
        size_t period = rths_proto_encode(&m, buf, sizeof buf);
        assert_int_equal(period, frame + 32 + 12 + 1 + (size_t)n * 3 * fourier); /* v3: +3 u32 */
        rths_msg_init(&m, RTHS_MSG_SET_TARGET, 0);
        m.u.target.dofs = n;
        m.u.target.harmonics = 1;
        size_t target = rths_proto_encode(&m, buf, sizeof buf);
        assert_int_equal(target, frame + 2 + (size_t)n * 16);
        rths_msg_init(&m, RTHS_MSG_TRACE, 0);
        m.u.trace.dofs = n;
        m.u.trace.count = RTHS_PROTO_MAX_TRACE_BATCH;
        size_t trace = rths_proto_encode(&m, buf, sizeof buf);
        assert_int_equal(trace, frame + 2 + RTHS_PROTO_MAX_TRACE_BATCH * (8 + (size_t)n * 40));
        print_message("n = %d: PERIOD %zu bytes (v1: %zu), SET_TARGET H=1 %zu (v1: %zu), "
                      "TRACE of 16 %zu (v1: %zu)\n",
                      n, period, frame + 32 + 3 * fourier, target, frame + 1 + 16, trace,
                      frame + 1 + 16 * 48);
    }
}

/* The fuzzer's seed corpus (fuzz/corpus/, written by fuzz/make_corpus.py from docs/protocol.md
 * with Python's struct and zlib, independently of this codec) decodes as its names say: every
 * well-formed frame to OK and back to exactly its bytes, every refused one with its status. */
static void test_seed_corpus(void **state) {
    (void)state;
    DIR *dir = opendir(rths_test_source_path("fuzz/corpus"));
    assert_non_null(dir);
    struct dirent *e;
    int files = 0, vectors = 0;
    while ((e = readdir(dir))) {
        if (e->d_name[0] == '.') continue;
        char path[4096];
        snprintf(path, sizeof path, "%s/%s", rths_test_source_path("fuzz/corpus"), e->d_name);
        static uint8_t data[2 * RTHS_PROTO_MAX_FRAME];
        FILE *f = fopen(path, "rb");
        assert_non_null(f);
        size_t n = fread(data, 1, sizeof data, f);
        fclose(f);
        const char *name = e->d_name;
        int want = RTHS_PROTO_OK;
        if (!strncmp(name, "bad_version", 11)) want = RTHS_PROTO_EVERSION;
        if (!strcmp(name, "bad_crc")) want = RTHS_PROTO_ECRC;
        if (!strcmp(name, "oversize")) want = RTHS_PROTO_EOVERSIZE;
        if (!strncmp(name, "bad_dofs", 8)) want = RTHS_PROTO_EPAYLOAD;
        if (!strcmp(name, "truncated")) want = RTHS_PROTO_INCOMPLETE;
        if (!strcmp(name, "unknown_type")) want = RTHS_PROTO_ETYPE;
        size_t pos = 0;
        int frames = 0;
        while (pos < n) {
            rths_msg m;
            size_t used = 0;
            int st = rths_proto_decode(data + pos, n - pos, &m, &used);
            if (st != want) fail_msg("fuzz/corpus/%s: %s", name, rths_proto_status_name(st));
            if (st == RTHS_PROTO_EPAYLOAD) assert_non_null(strstr(m.problem, "interface DoFs"));
            if (st != RTHS_PROTO_OK) break;
            uint8_t again[RTHS_PROTO_MAX_FRAME];
            assert_int_equal(rths_proto_encode(&m, again, sizeof again), used);
            assert_memory_equal(again, data + pos, used);
            vectors += m.type == RTHS_MSG_PERIOD && m.u.period.interface_dofs > 1;
            if (m.type == RTHS_MSG_PERIOD) { /* make_corpus.py: 3 late, 0 clipped, 1 saturated */
                assert_int_equal(m.u.period.late_samples, 3);
                assert_int_equal(m.u.period.clipped_demand_samples, 0);
                assert_int_equal(m.u.period.saturated_sensor_samples, 1);
            }
            if (!strcmp(name, "status_n2"))
                assert_string_equal(m.u.status.fault_detail,
                                    "demand limit: actuator 2 demand -10.4 V, beyond +-10 V");
            pos += used;
            frames++;
        }
        if (want == RTHS_PROTO_OK) assert_int_equal(frames, strcmp(name, "two_frames") ? 1 : 2);
        files++;
    }
    closedir(dir);
    assert_true(files >= 30);
    assert_int_equal(vectors, 2); /* PERIOD of 2 and of 4 interface DoFs */
}

/* docs/protocol.md's message tables are the message list of protocol.h: every row of the form
 * "| 0xNN | NAME | payload | reply |" (requests) or "| 0xNN | NAME | payload |" (controller to
 * host) equals the row the list gives, and every listed message has its row. A field added to the
 * list and not to the document (or the reverse) fails here. */
#define DOC_FIELD(kind, member, doc) doc,
#define DOC_ROW(name, code, direction, reply)                                                      \
    {code, #name, direction, reply,                                                                \
     (const char *const[]){RTHS_PROTO_PAYLOAD_##name(DOC_FIELD) NULL}},

typedef struct {
    int code;
    const char *name;
    int direction;
    const char *reply;
    const char *const *fields;
} doc_row;

static void expected_row(const doc_row *r, char *out, size_t cap) {
    char payload[1024] = "";
    for (int i = 0; r->fields[i]; i++)
        snprintf(payload + strlen(payload), sizeof payload - strlen(payload), "%s%s", i ? ", " : "",
                 r->fields[i]);
    if (!payload[0]) snprintf(payload, sizeof payload, "—");
    if (r->direction == RTHS_PROTO_REQUEST)
        snprintf(out, cap, "| 0x%02X | %s | %s | %s |", r->code, r->name, payload, r->reply);
    else
        snprintf(out, cap, "| 0x%02X | %s | %s |", r->code, r->name, payload);
}

static void test_document_tables_match_the_message_list(void **state) {
    (void)state;
    const doc_row rows[] = {RTHS_PROTO_MESSAGES(DOC_ROW)};
    const int n = (int)(sizeof rows / sizeof rows[0]);
    FILE *f = fopen(rths_test_source_path("docs/protocol.md"), "r");
    assert_non_null(f);
    char line[2048];
    int found[256] = {0}, doc_rows = 0, bad = 0;
    while (fgets(line, sizeof line, f)) {
        line[strcspn(line, "\n")] = '\0';
        unsigned code;
        if (sscanf(line, "| 0x%2x |", &code) != 1) continue;
        doc_rows++;
        int match = 0;
        for (int i = 0; i < n; i++) {
            if (rows[i].code != (int)code) continue;
            char want[2048];
            expected_row(&rows[i], want, sizeof want);
            if (strcmp(line, want) != 0) {
                print_message("docs/protocol.md:\n  %s\nthe message list says:\n  %s\n", line,
                              want);
                bad = 1;
            }
            found[code]++;
            match = 1;
        }
        if (!match) {
            print_message("docs/protocol.md documents type 0x%02X, not in the list: %s\n", code,
                          line);
            bad = 1;
        }
    }
    fclose(f);
    for (int i = 0; i < n; i++)
        if (found[rows[i].code] != 1) {
            char want[2048];
            expected_row(&rows[i], want, sizeof want);
            print_message("docs/protocol.md has %d rows for %s; expected once:\n  %s\n",
                          found[rows[i].code], rows[i].name, want);
            bad = 1;
        }
    assert_int_equal(doc_rows, n);
    assert_false(bad);
    /* The list also names the types: a sanity anchor on both ends of it. */
    assert_string_equal(rths_msg_type_name(RTHS_MSG_HELLO), "HELLO");
    assert_string_equal(rths_msg_type_name(0xFF), "ERROR");
    assert_string_equal(rths_msg_type_name(0x42), "unknown");
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_crc32_known_answer),
        cmocka_unit_test(test_known_answer_frames),
        cmocka_unit_test(test_round_trip_every_type),
        cmocka_unit_test(test_truncated_frames_are_incomplete),
        cmocka_unit_test(test_back_to_back_frames),
        cmocka_unit_test(test_header_errors_detected_early),
        cmocka_unit_test(test_maximum_payload_is_accepted_by_framing),
        cmocka_unit_test(test_every_bit_flip_is_caught),
        cmocka_unit_test(test_malformed_payloads),
        cmocka_unit_test(test_encoder_refuses_invalid_messages),
        cmocka_unit_test(test_dof_counts_are_bounded),
        cmocka_unit_test(test_version_one_peer),
        cmocka_unit_test(test_printable_text),
        cmocka_unit_test(test_frame_sizes),
        cmocka_unit_test(test_period_output_dofs),
        cmocka_unit_test(test_seed_corpus),
        cmocka_unit_test(test_document_tables_match_the_message_list),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
