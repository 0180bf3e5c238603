/* plx_scene_photo_size, and plx_scene_render without artefacts (the photo itself, no GPU work) and its argument checks,
 * which all happen before any rendering. The GPU path is tested in Rust (scene::render). */
#include "check.h"

int main(void) {
    plx_context *ctx = NULL;
    CHECK_STATUS(NULL, plx_context_new(NULL, &ctx), PLX_STATUS_OK);
    plx_scene *scene = NULL;
    CHECK_STATUS(ctx, plx_scene_new(ctx, &scene), PLX_STATUS_OK);

    enum { W = 8, H = 4 };
    uint8_t rgba[W * H * 4];
    plx_image_out out = {rgba, W, H, W * 4, PLX_PIXEL_FORMAT_RGBA8};
    plx_render_options opts;
    CHECK_STATUS(NULL, plx_render_options_init(&opts), PLX_STATUS_OK);
    CHECK(opts.size == sizeof opts && opts.shadow_map_size == 1024);

    /* No photo yet. */
    CHECK_STATUS(scene, plx_scene_render(scene, &opts, &out, NULL), PLX_STATUS_NOT_AVAILABLE);
    uint32_t pw = 0, ph = 0;
    CHECK_STATUS(scene, plx_scene_photo_size(scene, &pw, &ph), PLX_STATUS_NOT_AVAILABLE);
    CHECK(pw == 0 && ph == 0);

    uint8_t left[W * H * 3], right[W * H * 3];
    for (int i = 0; i < W * H * 3; i++) {
        left[i] = (uint8_t)(i * 37 + 11);
        right[i] = (uint8_t)(i * 37 + 11);
    }
    plx_image l = {left, W, H, W * 3, PLX_PIXEL_FORMAT_RGB8};
    plx_image r = {right, W, H, W * 3, PLX_PIXEL_FORMAT_RGB8};
    CHECK_STATUS(scene, plx_scene_set_stereo_pair(scene, &l, &r), PLX_STATUS_OK);
    /* The size every output must have. */
    CHECK_STATUS(scene, plx_scene_photo_size(scene, &pw, &ph), PLX_STATUS_OK);
    CHECK(pw == W && ph == H);
    CHECK_STATUS(scene, plx_scene_photo_size(scene, NULL, &ph), PLX_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(scene, plx_scene_photo_size(scene, &pw, NULL), PLX_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(NULL, plx_scene_photo_size(NULL, &pw, &ph), PLX_STATUS_NULL_ARGUMENT);

    /* No artefact: the composite is the photo, byte for byte, and alpha is opaque. */
    memset(rgba, 0, sizeof rgba);
    CHECK_STATUS(scene, plx_scene_render(scene, NULL, &out, NULL), PLX_STATUS_OK);
    int same = 1;
    for (int p = 0; p < W * H; p++) {
        for (int c = 0; c < 3; c++) same &= rgba[4 * p + c] == left[3 * p + c];
        same &= rgba[4 * p + 3] == 255;
    }
    CHECK(same);
    /* ... and no stereo was run for it. */
    char report[4096];
    CHECK_STATUS(scene, plx_scene_report(scene, report, sizeof report, NULL), PLX_STATUS_OK);
    CHECK(strstr(report, "no visible artefact") != NULL);
    CHECK(strstr(report, "\"stereo\"") == NULL);

    /* The coverage mask of nothing is zero. */
    float mask[W * H];
    for (int i = 0; i < W * H; i++) mask[i] = 7.0f;
    plx_image_out mask_out = {(uint8_t *)mask, W, H, W * sizeof(float), PLX_PIXEL_FORMAT_GRAY_F32};
    CHECK_STATUS(scene, plx_scene_render(scene, &opts, &out, &mask_out), PLX_STATUS_OK);
    for (int i = 0; i < W * H; i++) CHECK(mask[i] == 0.0f);

    /* Argument checks. */
    CHECK_STATUS(scene, plx_scene_render(scene, &opts, NULL, NULL), PLX_STATUS_NULL_ARGUMENT);
    plx_image_out small = out;
    small.width = W - 1;
    CHECK_STATUS(scene, plx_scene_render(scene, &opts, &small, NULL), PLX_STATUS_SIZE_MISMATCH);
    CHECK_MESSAGE(scene, "7x4");
    CHECK_STATUS(scene, plx_scene_render(scene, &opts, &out, &small), PLX_STATUS_SIZE_MISMATCH);
    plx_render_options bad = opts;
    bad.shading = 9;
    CHECK_STATUS(scene, plx_scene_render(scene, &bad, &out, NULL), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "shading mode");
    bad = opts;
    bad.shadows = 9;
    CHECK_STATUS(scene, plx_scene_render(scene, &bad, &out, NULL), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "shadow mode");
    bad = opts;
    bad.shadow_map_size = 64;
    CHECK_STATUS(scene, plx_scene_render(scene, &bad, &out, NULL), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "shadow");
    bad = opts;
    bad.size = 2;
    CHECK_STATUS(scene, plx_scene_render(scene, &bad, &out, NULL), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "plx_render_options_init");
    /* An old caller's shorter struct: the missing fields keep their defaults. */
    bad = opts;
    bad.size = offsetof(plx_render_options, shadow_map_size);
    bad.shadow_map_size = 64; /* beyond the caller's size: not read */
    CHECK_STATUS(scene, plx_scene_render(scene, &bad, &out, NULL), PLX_STATUS_OK);

    plx_scene_free(scene);
    plx_context_free(ctx);
    TEST_EXIT();
}
