/* The header every serialised jitterfmu FMU state starts with, its checksum, and the
 * checks of that header on restore: one definition for the native FMUs (jfcore.c) and
 * the container FMU (container.c), which differ only in their magic and what follows.
 *
 * Layout: magic (8 bytes) | layout version, byte-order mark (2 x uint32) | GUID (64
 * bytes, NUL padded) | the owner's 24 bytes (80..103) | the owner's data | FNV-1a 64 of
 * everything before it (8 bytes).  C99, header only (static functions).
 */
#ifndef JFSTATE_H
#define JFSTATE_H

#include <stdint.h>
#include <stdio.h>
#include <string.h>

#define JF_STATE_BOM 0x01020304u
#define JF_STATE_HEADER 104u

/* FNV-1a 64 of n bytes. */
static uint64_t jf_state_sum(const unsigned char *p, size_t n) {
    uint64_t h = 0xcbf29ce484222325u;
    size_t i;
    for (i = 0; i < n; i++) {
        h ^= p[i];
        h *= 0x100000001b3u;
    }
    return h;
}

/* Write magic, version, byte-order mark and GUID (bytes 0..79). */
static void jf_state_head_write(unsigned char *p, const char *magic, uint32_t version,
                                const char *guid) {
    uint32_t head[2];
    char g[64];
    memcpy(p, magic, 8);
    head[0] = version;
    head[1] = JF_STATE_BOM;
    memcpy(p + 8, head, 8);
    memset(g, 0, sizeof g);
    strncpy(g, guid, sizeof g - 1);
    memcpy(p + 16, g, 64);
}

/* 0 if bytes 0..79 of n bytes are a header of this magic, version and GUID; else 1 with
 * the reason, a sentence that follows "FMU state rejected: ", in why. */
static int jf_state_head_check(const unsigned char *p, size_t n, const char *magic,
                               uint32_t version, const char *guid, const char *kind,
                               char *why, size_t len) {
    uint32_t head[2];
    char g[64];
    if (n < JF_STATE_HEADER + 8u || memcmp(p, magic, 8) != 0) {
        snprintf(why, len, "not a jitterfmu %s state (%lu bytes)", kind, (unsigned long)n);
        return 1;
    }
    memcpy(head, p + 8, 8);
    if (head[1] != JF_STATE_BOM) {
        snprintf(why, len, "saved on a machine of another byte order");
        return 1;
    }
    if (head[0] != version) {
        snprintf(why, len, "layout version %u; expected %u", (unsigned)head[0],
                 (unsigned)version);
        return 1;
    }
    memset(g, 0, sizeof g);
    strncpy(g, guid, sizeof g - 1);
    if (memcmp(p + 16, g, 64) != 0) {
        snprintf(why, len, "saved by another model (GUID differs from %s)", guid);
        return 1;
    }
    return 0;
}

#endif
