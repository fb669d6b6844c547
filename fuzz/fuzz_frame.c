/* libFuzzer target for the controller link's frame decoder (make fuzz).
 *
 * Feeds the input to the decoder the way the controller's network thread does: frame after frame
 * from one receive buffer until the stream is exhausted or fatally malformed. Beyond "no crash, no
 * sanitizer report", it checks the codec's contract on every frame it accepts:
 *  - consumed bytes stay within the input and a fatal status consumes nothing;
 *  - the encoding is canonical: re-encoding a decoded message gives back exactly its bytes;
 *  - every interface-DoF count a decoded vector message carries (SET_TARGET, PERIOD, TRACE,
 *    STATUS, HELLO_REPLY) is within 1..RTHS_PROTO_MAX_DOFS, and a refused payload that names
 *    its problem does so in a terminated string;
 *  - a frame of another version (after RTHS_PROTO_EVERSION) is read the way a receiver reads a
 *    refusal across versions: rths_proto_decode_error_any_version stays within the input, and
 *    an ERROR it accepts re-encodes, framed in that version, to exactly its bytes.
 * A second pass runs over a copy whose checksums have been patched to match, so mutations reach
 * the payload decoders instead of dying at the CRC check. */
#include "rths/protocol.h"

#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static int dofs_ok(int n) {
    return n >= 1 && n <= RTHS_PROTO_MAX_DOFS;
}

/* The DoF counts of a decoded message: what the receiver sizes its loops by. */
static void check_dofs(const rths_msg *m) {
    int ok = 1;
    switch (m->type) {
    case RTHS_MSG_SET_TARGET:
        ok = dofs_ok(m->u.target.dofs);
        break;
    case RTHS_MSG_PERIOD:
        ok = dofs_ok(m->u.period.interface_dofs);
        break;
    case RTHS_MSG_TRACE:
        ok = dofs_ok(m->u.trace.dofs);
        break;
    case RTHS_MSG_STATUS:
        ok = dofs_ok(m->u.status.demand_v.n);
        break;
    case RTHS_MSG_HELLO_REPLY:
        ok = dofs_ok(m->u.hello_reply.interface_dofs);
        break;
    }
    if (!ok) abort();
}

/* A frame of another version, read as a refusal (an ERROR of any version). */
static void decode_other_version(const uint8_t *data, size_t size) {
    int version = rths_proto_frame_version(data, size);
    if (version < 0 || version == RTHS_PROTO_VERSION) abort(); /* EVERSION said otherwise */
    rths_msg m;
    size_t used = 0;
    int st = rths_proto_decode_error_any_version(data, size, &m, &used);
    if (used > size || (st != RTHS_PROTO_OK && st != RTHS_PROTO_EPAYLOAD && used != 0)) abort();
    if (st == RTHS_PROTO_OK) {
        if (m.type != RTHS_MSG_ERROR) abort();
        uint8_t again[RTHS_PROTO_MAX_FRAME];
        size_t n = rths_proto_encode_error_as(&m, version, again, sizeof again);
        /* versions this build cannot write (0, 3 and above) are only read */
        if (n && (n != used || memcmp(again, data, n) != 0)) abort();
        if (!n && version >= 1 && version <= RTHS_PROTO_VERSION) abort();
    }
}

static void decode_stream(const uint8_t *data, size_t size) {
    size_t pos = 0;
    while (pos < size) {
        rths_msg m;
        size_t used = 0;
        int st = rths_proto_decode(data + pos, size - pos, &m, &used);
        if (st == RTHS_PROTO_INCOMPLETE || rths_proto_status_is_fatal(st)) {
            if (used != 0) abort();
            if (st == RTHS_PROTO_EVERSION) decode_other_version(data + pos, size - pos);
            break;
        }
        if (used < RTHS_PROTO_HEADER_SIZE + RTHS_PROTO_CRC_SIZE || used > size - pos ||
            used > RTHS_PROTO_MAX_FRAME)
            abort();
        if (st == RTHS_PROTO_OK) {
            check_dofs(&m);
            uint8_t again[RTHS_PROTO_MAX_FRAME];
            size_t n = rths_proto_encode(&m, again, sizeof again);
            if (n != used || memcmp(again, data + pos, n) != 0) abort();
        } else if (st != RTHS_PROTO_ETYPE && st != RTHS_PROTO_EPAYLOAD) {
            abort();
        } else if (!memchr(m.problem, 0, sizeof m.problem)) {
            abort();
        }
        pos += used;
    }
}

/* Rewrites the CRC of every frame whose header parses, walking by the declared lengths. */
static void patch_crcs(uint8_t *buf, size_t size) {
    size_t pos = 0;
    while (size - pos >= RTHS_PROTO_HEADER_SIZE) {
        size_t plen = (size_t)buf[pos + 6] | (size_t)buf[pos + 7] << 8;
        size_t body = RTHS_PROTO_HEADER_SIZE + plen;
        if (plen > RTHS_PROTO_MAX_PAYLOAD || size - pos < body + RTHS_PROTO_CRC_SIZE) return;
        uint32_t c = rths_crc32(buf + pos, body);
        for (int i = 0; i < 4; i++)
            buf[pos + body + (size_t)i] = (uint8_t)(c >> (8 * i));
        pos += body + RTHS_PROTO_CRC_SIZE;
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    decode_stream(data, size);
    if (size > 0 && size <= 4 * RTHS_PROTO_MAX_FRAME) {
        uint8_t *copy = malloc(size);
        if (!copy) return 0;
        memcpy(copy, data, size);
        patch_crcs(copy, size);
        decode_stream(copy, size);
        free(copy);
    }
    return 0;
}
