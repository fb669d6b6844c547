/* libFuzzer target for the controller link's frame decoder (make fuzz).
 *
 * Feeds the input to the decoder the way the controller's network thread does: frame after frame
 * from one receive buffer until the stream is exhausted or fatally malformed. Beyond "no crash, no
 * sanitizer report", it checks the codec's contract on every frame it accepts:
 *  - consumed bytes stay within the input and a fatal status consumes nothing;
 *  - the encoding is canonical: re-encoding a decoded message gives back exactly its bytes.
 * A second pass runs over a copy whose checksums have been patched to match, so mutations reach
 * the payload decoders instead of dying at the CRC check. */
#include "rths/protocol.h"

#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void decode_stream(const uint8_t *data, size_t size) {
    size_t pos = 0;
    while (pos < size) {
        rths_msg m;
        size_t used = 0;
        int st = rths_proto_decode(data + pos, size - pos, &m, &used);
        if (st == RTHS_PROTO_INCOMPLETE || rths_proto_status_is_fatal(st)) {
            if (used != 0) abort();
            break;
        }
        if (used < RTHS_PROTO_HEADER_SIZE + RTHS_PROTO_CRC_SIZE || used > size - pos ||
            used > RTHS_PROTO_MAX_FRAME)
            abort();
        if (st == RTHS_PROTO_OK) {
            uint8_t again[RTHS_PROTO_MAX_FRAME];
            size_t n = rths_proto_encode(&m, again, sizeof again);
            if (n != used || memcmp(again, data + pos, n) != 0) abort();
        } else if (st != RTHS_PROTO_ETYPE && st != RTHS_PROTO_EPAYLOAD) {
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
