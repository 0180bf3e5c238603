/* A box GLB built by hand (JSON chunk + BIN chunk), shared by the C tests that need a model.
 * Include after check.h (it checks its own buffer sizes with CHECK). */
#ifndef PARALLAX_FFI_TESTS_BOX_GLB_H
#define PARALLAX_FFI_TESTS_BOX_GLB_H

#include <stdint.h>
#include <stdio.h>
#include <string.h>

/* The box: x in [-1, 1], y in [0, 0.5], z in [-0.5, 0.5] metres; no normals in the file, so the
 * loader generates them and warns. */
static const float BOX_MIN[3] = {-1.0f, 0.0f, -0.5f}, BOX_MAX[3] = {1.0f, 0.5f, 0.5f};

static void put_u32(uint8_t *p, uint32_t v) {
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

static void put_f32(uint8_t *p, float f) {
    uint32_t v;
    memcpy(&v, &f, 4);
    put_u32(p, v);
}

/* Writes the box GLB into `out` (at least 2048 bytes); returns its length. `uri` (may be NULL)
 * makes the buffer external instead of the BIN chunk. */
static size_t box_glb(uint8_t *out, const char *uri) {
    enum { NV = 8, NI = 36, BIN = NV * 12 + NI * 2 };
    /* Counter-clockwise seen from outside: -Y, +Y, -Z, +Z, -X, +X. */
    static const uint16_t idx[NI] = {0, 1, 2, 0, 2, 3, 4, 6, 5, 4, 7, 6, 0, 5, 1, 0, 4, 5,
                                      3, 2, 6, 3, 6, 7, 0, 3, 7, 0, 7, 4, 1, 5, 6, 1, 6, 2};
    char json[1024];
    int n = snprintf(
        json, sizeof json,
        "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[0]}],"
        "\"nodes\":[{\"mesh\":0,\"name\":\"box\"}],"
        "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"indices\":1}]}],"
        "\"buffers\":[{\"byteLength\":%d%s%s%s}],"
        "\"bufferViews\":[{\"buffer\":0,\"byteOffset\":0,\"byteLength\":%d},"
        "{\"buffer\":0,\"byteOffset\":%d,\"byteLength\":%d}],"
        "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":%d,\"type\":\"VEC3\","
        "\"min\":[%g,%g,%g],\"max\":[%g,%g,%g]},"
        "{\"bufferView\":1,\"componentType\":5123,\"count\":%d,\"type\":\"SCALAR\"}]}",
        BIN, uri ? ",\"uri\":\"" : "", uri ? uri : "", uri ? "\"" : "", NV * 12, NV * 12, NI * 2,
        NV, BOX_MIN[0], BOX_MIN[1], BOX_MIN[2], BOX_MAX[0], BOX_MAX[1], BOX_MAX[2], NI);
    while (n % 4) json[n++] = ' ';
    size_t at = 0;
    memcpy(out, "glTF", 4);
    put_u32(out + 4, 2);
    size_t total = 12 + 8 + (size_t)n + (uri ? 0 : 8 + BIN);
    put_u32(out + 8, (uint32_t)total);
    put_u32(out + 12, (uint32_t)n);
    memcpy(out + 16, "JSON", 4);
    memcpy(out + 20, json, (size_t)n);
    at = 20 + (size_t)n;
    if (!uri) {
        put_u32(out + at, BIN);
        memcpy(out + at + 4, "BIN\0", 4);
        at += 8;
        /* Corners: the bottom square (y min), then the top square above it. */
        const float corners[NV][3] = {
            {BOX_MIN[0], BOX_MIN[1], BOX_MIN[2]}, {BOX_MAX[0], BOX_MIN[1], BOX_MIN[2]},
            {BOX_MAX[0], BOX_MIN[1], BOX_MAX[2]}, {BOX_MIN[0], BOX_MIN[1], BOX_MAX[2]},
            {BOX_MIN[0], BOX_MAX[1], BOX_MIN[2]}, {BOX_MAX[0], BOX_MAX[1], BOX_MIN[2]},
            {BOX_MAX[0], BOX_MAX[1], BOX_MAX[2]}, {BOX_MIN[0], BOX_MAX[1], BOX_MAX[2]}};
        for (int v = 0; v < NV; v++)
            for (int k = 0; k < 3; k++) put_f32(out + at + (size_t)(v * 12 + k * 4), corners[v][k]);
        at += NV * 12;
        for (int i = 0; i < NI; i++) {
            out[at + (size_t)(2 * i)] = (uint8_t)idx[i];
            out[at + (size_t)(2 * i) + 1] = (uint8_t)(idx[i] >> 8);
        }
        at += NI * 2;
    }
    CHECK(at == total);
    return at;
}

#endif
