/* The single-producer single-consumer ring of fixed-size items that carries data between the
 * real-time loop and other threads (the step's published periods, the controller process's
 * commands and trace samples). Lock-free and wait-free: push and pop never block, allocate or
 * print, so the per-sample step may call them. Private to src/controller.
 *
 * The storage is the caller's (count_pow2 items of item_size bytes): the step embeds its ring in
 * its own struct, the process allocates its rings before the loop starts. */
#ifndef RTHS_CONTROLLER_SPSC_H
#define RTHS_CONTROLLER_SPSC_H

#include <stdatomic.h>
#include <stddef.h>
#include <string.h>

typedef struct rths_spsc {
    _Atomic size_t head; /* written by the producer only */
    _Atomic size_t tail; /* written by the consumer only */
    size_t mask, item_size;
    unsigned char *buf;
} rths_spsc;

/* count_pow2 must be a power of two. */
static inline void rths_spsc_init(rths_spsc *q, void *storage, size_t count_pow2,
                                  size_t item_size) {
    atomic_init(&q->head, 0);
    atomic_init(&q->tail, 0);
    q->mask = count_pow2 - 1;
    q->item_size = item_size;
    q->buf = storage;
}

/* Producer: 1 when queued, 0 when full (the item is not queued; never waited for). */
static inline int rths_spsc_push(rths_spsc *q, const void *item) {
    size_t h = atomic_load_explicit(&q->head, memory_order_relaxed);
    size_t t = atomic_load_explicit(&q->tail, memory_order_acquire);
    if (h - t > q->mask) return 0;
    memcpy(q->buf + (h & q->mask) * q->item_size, item, q->item_size);
    atomic_store_explicit(&q->head, h + 1, memory_order_release);
    return 1;
}

/* Consumer: 1 with the oldest item copied out, 0 when empty. */
static inline int rths_spsc_pop(rths_spsc *q, void *item) {
    size_t t = atomic_load_explicit(&q->tail, memory_order_relaxed);
    size_t h = atomic_load_explicit(&q->head, memory_order_acquire);
    if (t == h) return 0;
    memcpy(item, q->buf + (t & q->mask) * q->item_size, q->item_size);
    atomic_store_explicit(&q->tail, t + 1, memory_order_release);
    return 1;
}

#endif
