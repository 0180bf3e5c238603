/* The stereo stage through the C API: a textured pair shifted by 6 px, matched, then depth. */
#include <math.h>

#include "check.h"

enum { W = 96, H = 48, SHIFT = 6 };

static uint8_t texture(long x, long y) {
    unsigned long long v = (unsigned long long)(x * 73856093L) ^ (unsigned long long)(y * 19349663L);
    v ^= v >> 13;
    v *= 0x5bd1e995ull;
    return (uint8_t)(v >> 24);
}

static float at(const plx_float_view *v, unsigned x, unsigned y) {
    return *(const float *)((const uint8_t *)v->data + y * v->stride + x * sizeof(float));
}

int main(void) {
    static uint8_t left[W * H], right[W * H];
    for (long y = 0; y < H; y++)
        for (long x = 0; x < W; x++) {
            left[y * W + x] = texture(x, y);
            right[y * W + x] = texture(x + SHIFT, y); /* right view sees everything 6 px left */
        }
    plx_context *ctx = NULL;
    plx_scene *scene = NULL;
    CHECK_STATUS(NULL, plx_context_new(NULL, &ctx), PLX_STATUS_OK);
    CHECK_STATUS(ctx, plx_scene_new(ctx, &scene), PLX_STATUS_OK);

    /* Nothing to match yet. */
    plx_float_view view = {0};
    CHECK_STATUS(scene, plx_scene_disparity(scene, &view), PLX_STATUS_NOT_AVAILABLE);
    CHECK_MESSAGE(scene, "stereo pair");
    CHECK(view.data == NULL); /* untouched on failure */

    plx_image l = {left, W, H, W, PLX_PIXEL_FORMAT_GRAY8};
    plx_image r = {right, W, H, W, PLX_PIXEL_FORMAT_GRAY8};
    CHECK_STATUS(scene, plx_scene_set_stereo_pair(scene, &l, &r), PLX_STATUS_OK);

    plx_stereo_options opts;
    CHECK_STATUS(NULL, plx_stereo_options_init(&opts), PLX_STATUS_OK);
    opts.max_disparity = W; /* not less than the width */
    CHECK_STATUS(scene, plx_scene_set_stereo_options(scene, &opts), PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_scene_disparity(scene, &view), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "max_disparity");
    opts.preset = 42;
    CHECK_STATUS(scene, plx_scene_set_stereo_options(scene, &opts), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "preset");
    plx_stereo_options_init(&opts);
    opts.method = 9;
    CHECK_STATUS(scene, plx_scene_set_stereo_options(scene, &opts), PLX_STATUS_INVALID_ARGUMENT);

    plx_stereo_options_init(&opts);
    opts.max_disparity = 16;
    CHECK_STATUS(scene, plx_scene_set_stereo_options(scene, &opts), PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_scene_disparity(scene, &view), PLX_STATUS_OK);
    CHECK(view.width == W && view.height == H && view.stride >= W * sizeof(float));
    float d = at(&view, 60, 24);
    CHECK(fabsf(d - SHIFT) < 0.25f);

    plx_float_view conf = {0};
    CHECK_STATUS(scene, plx_scene_confidence(scene, &conf), PLX_STATUS_OK);
    for (unsigned y = 0; y < H; y++)
        for (unsigned x = 0; x < W; x++) {
            float c = at(&conf, x, y);
            CHECK(c >= 0.0f && c <= 1.0f);
        }

    /* Depth with a calibration: Z = f·B/d = 600 · 0.1 / 6 = 10 m. */
    plx_calibration calib = {600.0, W / 2.0, H / 2.0, 0.1, 0.0, 0};
    CHECK_STATUS(scene, plx_scene_set_calibration(scene, &calib), PLX_STATUS_OK);
    plx_float_view depth = {0};
    CHECK_STATUS(scene, plx_scene_depth(scene, &depth), PLX_STATUS_OK);
    CHECK(fabsf(at(&depth, 60, 24) - 10.0f) < 0.5f);

    /* The report of that call: stereo reused (only the calibration changed), depth computed. */
    char report[8192];
    CHECK_STATUS(scene, plx_scene_report(scene, report, sizeof report, NULL), PLX_STATUS_OK);
    CHECK(strstr(report, "\"name\": \"stereo\",\n      \"status\": \"reused\"") != NULL);
    CHECK(strstr(report, "\"name\": \"depth\",\n      \"status\": \"computed\"") != NULL);

    /* Sparse output keeps holes as NaN: the left border has no match. */
    opts.fill = 0;
    CHECK_STATUS(scene, plx_scene_set_stereo_options(scene, &opts), PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_scene_disparity(scene, &view), PLX_STATUS_OK);
    int holes = 0;
    for (unsigned y = 0; y < H; y++)
        for (unsigned x = 0; x < W; x++) holes += isnan(at(&view, x, y));
    CHECK(holes > 0);
    opts.fill = 2;
    CHECK_STATUS(scene, plx_scene_set_stereo_options(scene, &opts), PLX_STATUS_INVALID_ARGUMENT);

    /* NULL out-parameters. */
    CHECK_STATUS(scene, plx_scene_disparity(scene, NULL), PLX_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(scene, plx_scene_confidence(scene, NULL), PLX_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(scene, plx_scene_depth(scene, NULL), PLX_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(NULL, plx_stereo_options_init(NULL), PLX_STATUS_NULL_ARGUMENT);
    /* NULL options restore the defaults. */
    CHECK_STATUS(scene, plx_scene_set_stereo_options(scene, NULL), PLX_STATUS_OK);

    plx_scene_free(scene);
    plx_context_free(ctx);
    TEST_EXIT();
}
