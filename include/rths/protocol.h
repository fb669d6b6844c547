/* rths protocol: the binary link between the host (remote rig) and the controller process.
 *
 * docs/protocol.md is the normative description; this header is its C form. In short: every
 * message is one frame
 *
 *   offset 0  u8  magic 0x52 ('R')
 *          1  u8  magic 0x54 ('T')
 *          2  u8  protocol version (RTHS_PROTO_VERSION)
 *          3  u8  message type (rths_msg_type)
 *          4  u16 sequence number (requests: chosen by the host; replies echo it)
 *          6  u16 payload length L, 0 <= L <= RTHS_PROTO_MAX_PAYLOAD
 *          8  L bytes payload
 *        8+L  u32 CRC-32/ISO-HDLC of bytes [0, 8+L)
 *
 * All integers little-endian; doubles IEEE-754 binary64 little-endian; every double on the wire
 * must be finite. Sizes are bounded so both ends work in fixed buffers.
 *
 * The codec is pure (no I/O, no allocation): the controller's network thread, the remote rig and
 * the fuzzer all share it. It lives in controller/ because the controller owns the wire format;
 * rig/ (the host side) includes it downward. */
#ifndef RTHS_PROTOCOL_H
#define RTHS_PROTOCOL_H

#include <stddef.h>
#include <stdint.h>

#define RTHS_PROTO_VERSION 3
#define RTHS_PROTO_MAGIC0 0x52u
#define RTHS_PROTO_MAGIC1 0x54u
#define RTHS_PROTO_HEADER_SIZE 8
#define RTHS_PROTO_CRC_SIZE 4
/* the largest message, a PERIOD of 4 interface DoFs and 16 output DoFs, is 2746 bytes */
#define RTHS_PROTO_MAX_PAYLOAD 4096
#define RTHS_PROTO_MAX_FRAME (RTHS_PROTO_HEADER_SIZE + RTHS_PROTO_MAX_PAYLOAD + RTHS_PROTO_CRC_SIZE)
#define RTHS_PROTO_MAX_TEXT 200 /* bytes of a name or error message (no NUL on the wire) */
#define RTHS_PROTO_HARMONICS 5  /* coefficients k = 0..5 per signal in a PERIOD frame */
#define RTHS_PROTO_MAX_DOFS 4   /* interface DoFs (one actuator each) a frame carries */
#define RTHS_PROTO_MAX_TRACE_BATCH 16
#define RTHS_PROTO_MAX_OUTPUT_DOFS 16 /* output.dofs a PERIOD frame carries (signals.h) */
#define RTHS_PROTO_LATENCY_BINS 16

/* The message list, the one table the codec, the type names and docs/protocol.md's message
 * tables come from: X(NAME, code, direction, reply). direction: RTHS_PROTO_REQUEST (host to
 * controller; reply names the answer) or RTHS_PROTO_REPLY (controller to host; reply ""). Each
 * message's payload, in wire order, is RTHS_PROTO_PAYLOAD_<NAME>(F): F(kind, member, doc) per
 * field, kind the wire encoding (u8, u16, u32, u64, f64, text, latency_hist, dof_values,
 * target_dofs, period_dofs, trace_batch), member the field of rths_msg.u, doc its
 * docs/protocol.md description (tests/test_protocol.c fails when the document's tables and this
 * list disagree). */
#define RTHS_PROTO_MESSAGES(X)                                                                     \
    X(HELLO, 0x01, RTHS_PROTO_REQUEST, "HELLO_REPLY")                                              \
    X(ARM, 0x02, RTHS_PROTO_REQUEST, "ACK")                                                        \
    X(DISARM, 0x03, RTHS_PROTO_REQUEST, "ACK")                                                     \
    X(SET_FORCING, 0x04, RTHS_PROTO_REQUEST, "ACK")                                                \
    X(SET_TARGET, 0x05, RTHS_PROTO_REQUEST, "ACK")                                                 \
    X(GET_STATUS, 0x06, RTHS_PROTO_REQUEST, "STATUS")                                              \
    X(GET_COEFFS, 0x07, RTHS_PROTO_REQUEST, "PERIOD (the latest whole period)")                    \
    X(SUBSCRIBE, 0x08, RTHS_PROTO_REQUEST, "ACK")                                                  \
    X(RESET_FAULT, 0x09, RTHS_PROTO_REQUEST, "ACK")                                                \
    X(PING, 0x0A, RTHS_PROTO_REQUEST, "ACK")                                                       \
    X(HELLO_REPLY, 0x81, RTHS_PROTO_REPLY, "")                                                     \
    X(ACK, 0x82, RTHS_PROTO_REPLY, "")                                                             \
    X(STATUS, 0x83, RTHS_PROTO_REPLY, "")                                                          \
    X(PERIOD, 0x84, RTHS_PROTO_REPLY, "")                                                          \
    X(TRACE, 0x85, RTHS_PROTO_REPLY, "")                                                           \
    X(ERROR, 0xFF, RTHS_PROTO_REPLY, "")

#define RTHS_PROTO_REQUEST 0
#define RTHS_PROTO_REPLY 1

#define RTHS_PROTO_PAYLOAD_HELLO(F)                                                                \
    F(u16, hello.version, "u16 version (=3)")                                                      \
    F(text, hello.name, "text client name")
#define RTHS_PROTO_PAYLOAD_ARM(F)
#define RTHS_PROTO_PAYLOAD_DISARM(F)
#define RTHS_PROTO_PAYLOAD_SET_FORCING(F)                                                          \
    F(f64, forcing.frequency_hz, "f64 frequency (Hz)")                                             \
    F(f64, forcing.amplitude_n, "f64 amplitude (N)")
#define RTHS_PROTO_PAYLOAD_SET_TARGET(F)                                                           \
    F(target_dofs, target,                                                                         \
      "u8 n interface DoFs (1..4), u8 H (0..5), then n × (f64 a[H], f64 b[H]) (m)")
#define RTHS_PROTO_PAYLOAD_GET_STATUS(F)
#define RTHS_PROTO_PAYLOAD_GET_COEFFS(F)
#define RTHS_PROTO_PAYLOAD_SUBSCRIBE(F)                                                            \
    F(u8, subscribe.flags, "u8 flags (bit 0: periods, bit 1: traces; other bits 0)")               \
    F(u32, subscribe.trace_decimation, "u32 trace decimation (>= 1)")
#define RTHS_PROTO_PAYLOAD_RESET_FAULT(F)
#define RTHS_PROTO_PAYLOAD_PING(F)
#define RTHS_PROTO_PAYLOAD_HELLO_REPLY(F)                                                          \
    F(u16, hello_reply.version, "u16 version")                                                     \
    F(u8, hello_reply.max_harmonics, "u8 max harmonics (5)")                                       \
    F(u8, hello_reply.interface_dofs, "u8 interface DoFs n (1..4, one actuator each)")             \
    F(f64, hello_reply.sample_period_s, "f64 sample period (s)")                                   \
    F(f64, hello_reply.watchdog_s, "f64 watchdog time (s)")                                        \
    F(f64, hello_reply.noise_level_m, "f64 displacement noise std (m)")                            \
    F(text, hello_reply.name, "text controller description")
#define RTHS_PROTO_PAYLOAD_ACK(F)                                                                  \
    F(u8, ack.acked_type, "u8 acknowledged type")                                                  \
    F(f64, ack.time_s,                                                                             \
      "f64 controller time (s) at which the command took effect (SET_FORCING, SET_TARGET: from "   \
      "which periods run it, below)")
#define RTHS_PROTO_PAYLOAD_STATUS(F)                                                               \
    F(f64, status.time_s, "f64 time (s)")                                                          \
    F(u8, status.flags, "u8 flags")                                                                \
    F(u8, status.fault, "u8 fault")                                                                \
    F(u8, status.last_disarm, "u8 last disarm reason")                                             \
    F(f64, status.frequency_hz, "f64 forcing frequency (Hz)")                                      \
    F(f64, status.amplitude_n, "f64 forcing amplitude (N)")                                        \
    F(u64, status.samples, "u64 loop cycles run")                                                  \
    F(u64, status.overruns, "u64 overruns")                                                        \
    F(f64, status.worst_lateness_s, "f64 worst wake-up lateness (s)")                              \
    F(u64, status.periods_dropped, "u64 periods dropped")                                          \
    F(latency_hist, status.latency_hist, "16 × u64 lateness histogram counts")                     \
    F(dof_values, status.demand_v, "u8 n (1..4), n × f64 actuator demand (V)")                     \
    F(text, status.fault_detail, "text fault detail")
#define RTHS_PROTO_PAYLOAD_PERIOD(F)                                                               \
    F(u32, period.index, "u32 index")                                                              \
    F(f64, period.frequency_hz, "f64 frequency (Hz)")                                              \
    F(f64, period.start_time_s, "f64 start time (s)")                                              \
    F(f64, period.end_time_s, "f64 end time (s)")                                                  \
    F(u32, period.samples, "u32 samples")                                                          \
    F(u32, period.late_samples, "u32 late samples")                                                \
    F(u32, period.clipped_demand_samples, "u32 clipped-demand samples")                            \
    F(u32, period.saturated_sensor_samples, "u32 saturated-sensor samples")                        \
    F(period_dofs, period,                                                                         \
      "u8 n interface DoFs (1..4), then n × (fourier physical interface displacement (m), "       \
      "fourier numerical interface displacement (m), fourier load-cell force (N))")                \
    F(output_dofs, period,                                                                         \
      "only with output.dofs: u8 m output DoFs (1..16), then m × fourier displacement (m or rad)")
#define RTHS_PROTO_PAYLOAD_TRACE(F)                                                                \
    F(trace_batch, trace,                                                                          \
      "u8 n interface DoFs (1..4), u8 count (1..16), then count × (f64 time (s), n × (x_phys "   \
      "(m), x_num (m), target (m), force (N), demand (V)))")
#define RTHS_PROTO_PAYLOAD_ERROR(F)                                                                \
    F(u16, error.code, "u16 code (§2)")                                                            \
    F(u8, error.request_type, "u8 request type")                                                   \
    F(text, error.message, "text message")

typedef enum rths_msg_type {
#define RTHS_PROTO_X_ENUM(name, code, direction, reply) RTHS_MSG_##name = code,
    RTHS_PROTO_MESSAGES(RTHS_PROTO_X_ENUM)
#undef RTHS_PROTO_X_ENUM
} rths_msg_type;

/* Decoder results; the nonzero values are also the error codes carried by ERROR frames. */
typedef enum rths_proto_status {
    RTHS_PROTO_OK = 0,
    RTHS_PROTO_INCOMPLETE = 1, /* not a whole frame yet: read more bytes */
    RTHS_PROTO_EMAGIC = 2,     /* framing lost: the bytes are not a frame start (fatal) */
    RTHS_PROTO_EVERSION = 3,   /* a protocol version this end does not speak (fatal) */
    RTHS_PROTO_EOVERSIZE = 4,  /* payload length above RTHS_PROTO_MAX_PAYLOAD (fatal) */
    RTHS_PROTO_ECRC = 5,       /* checksum mismatch (fatal) */
    RTHS_PROTO_ETYPE = 6,      /* well-framed, unknown message type */
    RTHS_PROTO_EPAYLOAD = 7,   /* well-framed, payload malformed for its type */
    /* codes used only in ERROR frames (server-side refusals) */
    RTHS_PROTO_EBUSY = 8,    /* another client holds the armed controller */
    RTHS_PROTO_ESTATE = 9,   /* command not valid now (e.g. before HELLO, arm while faulted) */
    RTHS_PROTO_ERANGE = 10,  /* value outside the controller's configured limits */
    RTHS_PROTO_ENODATA = 11, /* GET_COEFFS before any whole period */
} rths_proto_status;

/* Fatal statuses mean the byte stream can no longer be trusted: the receiver answers with an
 * ERROR frame (best effort) and closes the connection. */
int rths_proto_status_is_fatal(int status);
const char *rths_proto_status_name(int status);
const char *rths_msg_type_name(int type);

/* CRC-32/ISO-HDLC (the zlib/Ethernet CRC): reflected polynomial 0xEDB88320, init 0xFFFFFFFF,
 * final xor 0xFFFFFFFF. Known answer: crc32("123456789") = 0xCBF43926. */
uint32_t rths_crc32(const uint8_t *data, size_t len);

/* Fourier coefficients k = 0..RTHS_PROTO_HARMONICS of one signal over one period (b[0] = 0). */
typedef struct rths_proto_fourier {
    double a[RTHS_PROTO_HARMONICS + 1];
    double b[RTHS_PROTO_HARMONICS + 1];
} rths_proto_fourier;

/* Controller status flags. */
#define RTHS_STATUS_ARMED 0x01u
#define RTHS_STATUS_CLIENT_OWNS 0x02u /* the asking client holds the control connection */
#define RTHS_STATUS_RT_FIFO 0x04u     /* loop thread runs SCHED_FIFO */
#define RTHS_STATUS_RT_MLOCK 0x08u    /* memory locked (mlockall) */
#define RTHS_STATUS_RT_PINNED 0x10u   /* loop thread pinned to one CPU */

/* Lateness histogram bin upper edges, seconds (last bin: everything above the previous edge). */
extern const double rths_proto_latency_edges_s[RTHS_PROTO_LATENCY_BINS];

/* A value per interface DoF (DoF d at v[d], d < n). */
typedef struct rths_proto_dof_values {
    int n; /* 1..RTHS_PROTO_MAX_DOFS on the wire (0 encodes as 1) */
    double v[RTHS_PROTO_MAX_DOFS];
} rths_proto_dof_values;

typedef struct rths_proto_status_msg {
    double time_s;       /* controller (rig) time: samples run * sample period */
    uint8_t flags;       /* RTHS_STATUS_* */
    uint8_t fault;       /* latched fault, rths_rig_fault numbering (0: none) */
    uint8_t last_disarm; /* why the controller last disarmed: rths_disarm_reason */
    double frequency_hz; /* forcing in effect */
    double amplitude_n;
    uint64_t samples;         /* loop cycles run */
    uint64_t overruns;        /* cycles that started after the next deadline had passed */
    double worst_lateness_s;  /* largest wake-up lateness seen */
    uint64_t periods_dropped; /* per-period records the network side could not keep up with */
    uint64_t latency_hist[RTHS_PROTO_LATENCY_BINS];
    rths_proto_dof_values demand_v; /* every actuator's demand after the last sample, V */
    /* version 3: what latched the fault, naming the channel, the value and the limit (e.g.
     * "demand limit: actuator 1 demand -10.4 V, beyond +-10 V"); empty without a fault */
    char fault_detail[RTHS_PROTO_MAX_TEXT + 1];
} rths_proto_status_msg;

/* Why the controller is (or was last) disarmed. */
typedef enum rths_disarm_reason {
    RTHS_DISARM_NONE = 0,     /* never armed */
    RTHS_DISARM_COMMAND = 1,  /* DISARM from the host */
    RTHS_DISARM_FAULT = 2,    /* a limit or non-finite signal latched a fault */
    RTHS_DISARM_WATCHDOG = 3, /* host silent longer than the watchdog time */
    RTHS_DISARM_LINK = 4,     /* the control connection closed or sent a fatal frame */
    RTHS_DISARM_SHUTDOWN = 5, /* the controller process is stopping */
} rths_disarm_reason;

typedef struct rths_proto_period {
    uint32_t index; /* period counter since the controller started */
    double frequency_hz;
    double start_time_s; /* controller time at the period's first sample */
    double end_time_s;   /* ... and at its end */
    uint32_t samples;
    /* version 3: the period's integrity (signals.h, rths_period): samples that missed their
     * deadline, in which an actuator demand was clamped, in which a converter sat at full
     * scale; each at most samples */
    uint32_t late_samples, clipped_demand_samples, saturated_sensor_samples;
    rths_proto_fourier phys;  /* physical interface displacement, m (the first interface DoF) */
    rths_proto_fourier num;   /* numerical interface displacement, m (the first interface DoF) */
    rths_proto_fourier force; /* load cell, N (the first interface DoF) */
    /* interface DoFs carried (1..RTHS_PROTO_MAX_DOFS; 0 encodes as 1) and, for d >= 1, DoF d's
     * coefficients ([0] unused: the first DoF is phys, num and force above) */
    int interface_dofs;
    rths_proto_fourier phys_dof[RTHS_PROTO_MAX_DOFS];
    rths_proto_fourier num_dof[RTHS_PROTO_MAX_DOFS];
    rths_proto_fourier force_dof[RTHS_PROTO_MAX_DOFS];
    /* output.dofs (rths_period.output_dof): the listed DoFs' displacements, m or rad, in the
     * list's order. 0: none, and the frame ends after the interface DoFs, as without them */
    int output_dofs;
    rths_proto_fourier output_dof[RTHS_PROTO_MAX_OUTPUT_DOFS];
} rths_proto_period;

/* One trace sample: the scalars are the first interface DoF's; for d >= 1, DoF d's signals are
 * at index d of the arrays ([0] unused). */
typedef struct rths_proto_trace_sample {
    double time_s, x_phys_m, x_num_m, target_m, force_n, demand;
    double x_phys_dof_m[RTHS_PROTO_MAX_DOFS], x_num_dof_m[RTHS_PROTO_MAX_DOFS];
    double target_dof_m[RTHS_PROTO_MAX_DOFS], force_dof_n[RTHS_PROTO_MAX_DOFS];
    double demand_dof[RTHS_PROTO_MAX_DOFS];
} rths_proto_trace_sample;

/* SET_TARGET's payload: for interface DoF d < dofs, x*_d(t) = sum_{k=1..harmonics}
 * a[d * harmonics + k-1] cos(k w t) + b[d * harmonics + k-1] sin(k w t), the layout of
 * rths_rig_set_target_dofs (one DoF: a[k-1], b[k-1]). dofs 0 encodes as 1. */
typedef struct rths_proto_target {
    int harmonics;
    double a[RTHS_PROTO_MAX_DOFS * RTHS_PROTO_HARMONICS],
        b[RTHS_PROTO_MAX_DOFS * RTHS_PROTO_HARMONICS];
    int dofs;
} rths_proto_target;

typedef struct rths_proto_trace {
    int count;
    int dofs; /* interface DoFs each sample carries, 1..RTHS_PROTO_MAX_DOFS (0 encodes as 1) */
    rths_proto_trace_sample s[RTHS_PROTO_MAX_TRACE_BATCH];
} rths_proto_trace;

#define RTHS_SUBSCRIBE_PERIODS 0x01u
#define RTHS_SUBSCRIBE_TRACES 0x02u

typedef struct rths_msg {
    uint8_t type; /* rths_msg_type */
    uint16_t seq;
    union {
        struct {
            uint16_t version;
            char name[RTHS_PROTO_MAX_TEXT + 1];
        } hello;
        struct {
            uint16_t version;
            uint8_t max_harmonics;
            uint8_t interface_dofs; /* 1..RTHS_PROTO_MAX_DOFS: the length of every vector */
            double sample_period_s, watchdog_s, noise_level_m;
            char name[RTHS_PROTO_MAX_TEXT + 1];
        } hello_reply;
        struct {
            double frequency_hz, amplitude_n;
        } forcing;
        rths_proto_target target;
        struct {
            uint8_t flags;
            uint32_t trace_decimation;
        } subscribe;
        /* time_s: controller time at which the command took effect; set target: later periods
         * with start_time_s >= time_s ran entirely under it; set forcing: those with
         * start_time_s >= time_s - h/2 run it, the earlier ones ran the one before
         * (rths_controller_forcing_valid_from_s, docs/protocol.md). */
        struct {
            uint8_t acked_type;
            double time_s;
        } ack;
        rths_proto_status_msg status;
        rths_proto_period period;
        rths_proto_trace trace;
        struct {
            uint16_t code;
            uint8_t request_type;
            char message[RTHS_PROTO_MAX_TEXT + 1];
        } error;
    } u;
    /* set by the decoder on RTHS_PROTO_EPAYLOAD when it can name the problem (e.g. "5 interface
     * DoFs; the protocol carries 1..4"), else empty */
    char problem[96];
} rths_msg;

/* Encodes msg into buf (cap bytes). Returns the frame length, or 0 when msg is invalid (unknown
 * type, out-of-range counts, non-finite doubles, text too long) or cap is too small. */
size_t rths_proto_encode(const rths_msg *msg, uint8_t *buf, size_t cap);

/* Decodes the frame at the start of buf[0..len). Returns an rths_proto_status.
 * - RTHS_PROTO_OK: *msg filled, *consumed = frame length.
 * - RTHS_PROTO_INCOMPLETE: nothing consumed; call again with more bytes.
 * - fatal statuses: *consumed = 0; the stream is unusable.
 * - RTHS_PROTO_ETYPE / EPAYLOAD: the frame was well-formed (checksum good), *consumed = its length
 *   so the receiver can skip it; msg->type and msg->seq are set for the error reply.
 * Errors are detected as early as possible: a bad magic, version or length fails on the header
 * bytes alone, without waiting for the rest. Never reads outside buf[0..len). */
int rths_proto_decode(const uint8_t *buf, size_t len, rths_msg *msg, size_t *consumed);

/* The version byte of the frame starting at buf (-1: fewer than 3 bytes, or not a frame start).
 * For naming a peer's version after RTHS_PROTO_EVERSION. */
int rths_proto_frame_version(const uint8_t *buf, size_t len);

/* "peer speaks rths protocol version V; this build speaks version 3", into out. */
void rths_proto_version_message(char *out, size_t cap, int peer_version);

/* The ERROR frame's layout (u16 code, u8 request type, text) is the same in every version, so a
 * peer of another version can be told why it is refused in frames it reads, and can read such a
 * refusal: rths_proto_encode_error_as frames msg (an ERROR) as `version` (1..RTHS_PROTO_VERSION;
 * 0 on anything else), rths_proto_decode_error_any_version decodes an ERROR frame of any
 * version (RTHS_PROTO_OK, or a decoder status; a frame of another type is RTHS_PROTO_ETYPE). */
size_t rths_proto_encode_error_as(const rths_msg *msg, int version, uint8_t *buf, size_t cap);
int rths_proto_decode_error_any_version(const uint8_t *buf, size_t len, rths_msg *msg,
                                        size_t *consumed);

/* A peer's text (a HELLO's client name, a controller description) as it may be shown to an
 * operator: printable ASCII only (every other byte, a newline or an escape, becomes '?'), at
 * most max_chars characters (longer: cut, "..." appended); out holds at least max_chars + 4. */
void rths_proto_printable(const char *in, size_t max_chars, char *out, size_t cap);

/* Convenience builders. */
void rths_msg_init(rths_msg *msg, int type, uint16_t seq);
void rths_msg_error(rths_msg *msg, uint16_t seq, int code, int request_type, const char *fmt, ...)
    __attribute__((format(printf, 5, 6)));

#endif
