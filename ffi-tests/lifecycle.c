/* Handles are created, used and freed; versions agree; a context needs no GPU. */
#include "check.h"

int main(void) {
    /* The header and the library agree on the version. */
    CHECK(strcmp(plx_version(), PLX_VERSION_STRING) == 0);

    /* Default context from NULL options, and from initialised options. */
    plx_context *ctx = NULL;
    CHECK_STATUS(NULL, plx_context_new(NULL, &ctx), PLX_STATUS_OK);
    CHECK(ctx != NULL);

    plx_context_options opts;
    CHECK_STATUS(NULL, plx_context_options_init(&opts), PLX_STATUS_OK);
    CHECK(opts.size == sizeof opts);
    CHECK(opts.max_image_pixels == 64ull * 1024 * 1024);
    opts.max_image_pixels = 1000;
    opts.adapter_name = "no adapter needed to create a context";
    plx_context *small = NULL;
    CHECK_STATUS(NULL, plx_context_new(&opts, &small), PLX_STATUS_OK);

    /* Scenes; a scene outlives the context it was made from. */
    plx_scene *scene = NULL;
    CHECK_STATUS(ctx, plx_scene_new(ctx, &scene), PLX_STATUS_OK);
    plx_scene *other = NULL;
    CHECK_STATUS(small, plx_scene_new(small, &other), PLX_STATUS_OK);
    plx_context_free(small);

    /* A strided BGRA pair: 5x3 pixels, rows padded to 24 bytes. */
    uint8_t pixels[24 * 3];
    for (size_t i = 0; i < sizeof pixels; i++) pixels[i] = (uint8_t)(i * 7);
    plx_image left = {pixels, 5, 3, 24, PLX_PIXEL_FORMAT_BGRA8};
    plx_image right = left;
    CHECK_STATUS(scene, plx_scene_set_stereo_pair(scene, &left, &right), PLX_STATUS_OK);
    CHECK_STATUS(other, plx_scene_set_stereo_pair(other, &left, &right), PLX_STATUS_OK);

    /* Every pixel format is accepted. */
    static float floats[4 * 4 * 2];
    plx_image f32 = {(const uint8_t *)floats, 2, 2, 2 * 16, PLX_PIXEL_FORMAT_RGBA_F32};
    CHECK_STATUS(scene, plx_scene_set_stereo_pair(scene, &f32, &f32), PLX_STATUS_OK);
    plx_image f16 = {(const uint8_t *)floats, 2, 2, 2 * 8, PLX_PIXEL_FORMAT_RGBA_F16};
    CHECK_STATUS(scene, plx_scene_set_stereo_pair(scene, &f16, &f16), PLX_STATUS_OK);
    plx_image gray = {pixels, 5, 3, 24, PLX_PIXEL_FORMAT_GRAY8};
    CHECK_STATUS(scene, plx_scene_set_stereo_pair(scene, &gray, &gray), PLX_STATUS_OK);

    /* Calibration: accepted when sane, rejected with a message naming the value otherwise. */
    plx_calibration calib = {500.0, 2.5, 1.5, 0.1, 0.0, 4};
    CHECK_STATUS(scene, plx_scene_set_calibration(scene, &calib), PLX_STATUS_OK);

    /* The report is JSON with the documented keys, even before any product was asked for. */
    size_t report_len = 0;
    CHECK_STATUS(scene, plx_scene_report(scene, NULL, 0, &report_len), PLX_STATUS_OK);
    CHECK(report_len > 10);
    char *report = malloc(report_len);
    CHECK_STATUS(scene, plx_scene_report(scene, report, report_len, NULL), PLX_STATUS_OK);
    CHECK(strstr(report, "\"version\": \"" PLX_VERSION_STRING "\"") != NULL);
    CHECK(strstr(report, "\"stages\"") != NULL);
    CHECK(strlen(report) + 1 == report_len);
    free(report);

    /* No failure yet on this scene: the message is empty. */
    char msg[16] = "untouched";
    size_t needed = 0;
    CHECK_STATUS(NULL, plx_last_error_message(scene, msg, sizeof msg, &needed), PLX_STATUS_OK);
    CHECK(msg[0] == '\0');
    CHECK(needed == 1);

    plx_scene_free(other);
    plx_scene_free(scene);
    plx_context_free(ctx);
    /* NULL is allowed. */
    plx_scene_free(NULL);
    plx_context_free(NULL);
    TEST_EXIT();
}
