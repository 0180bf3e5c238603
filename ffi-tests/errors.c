/* Every error path of the foundation's functions returns its status and a message naming the
 * problem, and leaves the handle usable. */
#include "check.h"

int main(void) {
    plx_context *ctx = NULL;
    plx_scene *scene = NULL;

    /* NULL out-parameters and handles. */
    CHECK_STATUS(NULL, plx_context_new(NULL, NULL), PLX_STATUS_NULL_ARGUMENT);
    CHECK_MESSAGE(NULL, "out");
    CHECK_STATUS(NULL, plx_context_options_init(NULL), PLX_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(NULL, plx_scene_new(NULL, &scene), PLX_STATUS_NULL_ARGUMENT);
    CHECK_MESSAGE(NULL, "context");
    CHECK(scene == NULL); /* outputs are written only on success */

    /* Options: a size too small to hold even `size`, and a zero pixel cap. */
    plx_context_options opts;
    plx_context_options_init(&opts);
    opts.size = 1;
    CHECK_STATUS(NULL, plx_context_new(&opts, &ctx), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(NULL, "size");
    plx_context_options_init(&opts);
    opts.max_image_pixels = 0;
    CHECK_STATUS(NULL, plx_context_new(&opts, &ctx), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(NULL, "max_image_pixels");
    CHECK(ctx == NULL);

    /* An older caller that only knows `size` and `max_image_pixels` still works. */
    plx_context_options_init(&opts);
    opts.size = sizeof(size_t) + sizeof(uint64_t);
    opts.max_image_pixels = 100;
    opts.adapter_name = (const char *)1; /* beyond the caller's size: must not be read */
    CHECK_STATUS(NULL, plx_context_new(&opts, &ctx), PLX_STATUS_OK);
    CHECK_STATUS(ctx, plx_scene_new(ctx, &scene), PLX_STATUS_OK);

    /* A context is not a scene. */
    uint8_t px[64 * 4] = {0};
    plx_image ok = {px, 8, 8, 8, PLX_PIXEL_FORMAT_GRAY8};
    CHECK_STATUS(NULL, plx_scene_set_stereo_pair((plx_scene *)ctx, &ok, &ok), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(NULL, "scene");
    CHECK_STATUS(NULL, plx_scene_set_stereo_pair(NULL, &ok, &ok), PLX_STATUS_NULL_ARGUMENT);

    /* Bad image descriptors. */
    CHECK_STATUS(scene, plx_scene_set_stereo_pair(scene, NULL, &ok), PLX_STATUS_NULL_ARGUMENT);
    CHECK_MESSAGE(scene, "left");
    plx_image nodata = {NULL, 8, 8, 8, PLX_PIXEL_FORMAT_GRAY8};
    CHECK_STATUS(scene, plx_scene_set_stereo_pair(scene, &ok, &nodata), PLX_STATUS_NULL_ARGUMENT);
    CHECK_MESSAGE(scene, "right.data");
    plx_image zero = {px, 0, 8, 8, PLX_PIXEL_FORMAT_GRAY8};
    CHECK_STATUS(scene, plx_scene_set_stereo_pair(scene, &zero, &zero), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "zero");
    plx_image short_stride = {px, 8, 8, 7, PLX_PIXEL_FORMAT_GRAY8};
    CHECK_STATUS(scene, plx_scene_set_stereo_pair(scene, &short_stride, &ok), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "stride");
    plx_image bad_format = {px, 8, 8, 8, 99};
    CHECK_STATUS(scene, plx_scene_set_stereo_pair(scene, &bad_format, &ok), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "pixel format 99");
    plx_image other_size = {px, 8, 4, 8, PLX_PIXEL_FORMAT_GRAY8};
    CHECK_STATUS(scene, plx_scene_set_stereo_pair(scene, &ok, &other_size), PLX_STATUS_SIZE_MISMATCH);
    CHECK_MESSAGE(scene, "8x4");
    /* 11 x 10 = 110 pixels is over this context's cap of 100. */
    plx_image big = {px, 11, 10, 11, PLX_PIXEL_FORMAT_GRAY8};
    CHECK_STATUS(scene, plx_scene_set_stereo_pair(scene, &big, &big), PLX_STATUS_TOO_LARGE);
    CHECK_MESSAGE(scene, "cap");

    /* Calibration with a negative baseline or a NaN focal length. */
    plx_calibration calib = {500.0, 4.0, 4.0, -0.1, 0.0, 0};
    CHECK_STATUS(scene, plx_scene_set_calibration(scene, &calib), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "baseline");
    calib.baseline_m = 0.1;
    calib.focal_px = 0.0 / 0.0;
    CHECK_STATUS(scene, plx_scene_set_calibration(scene, &calib), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "focal");
    CHECK_STATUS(scene, plx_scene_set_calibration(scene, NULL), PLX_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(scene, plx_scene_report(scene, NULL, 4, NULL), PLX_STATUS_NULL_ARGUMENT);

    /* Message truncation works like snprintf and reports the full size. */
    char tiny[4];
    size_t needed = 0;
    CHECK_STATUS(NULL, plx_last_error_message(scene, tiny, sizeof tiny, &needed), PLX_STATUS_OK);
    CHECK(strlen(tiny) == 3);
    CHECK(needed > sizeof tiny);
    CHECK_STATUS(NULL, plx_last_error_message(scene, NULL, 0, &needed), PLX_STATUS_OK);
    CHECK_STATUS(NULL, plx_last_error_message(scene, NULL, 8, &needed), PLX_STATUS_NULL_ARGUMENT);

    /* Status strings: distinct for known codes, a fallback for unknown ones. */
    CHECK(strcmp(plx_status_str(PLX_STATUS_OK), "ok") == 0);
    CHECK(strcmp(plx_status_str(PLX_STATUS_PANIC), plx_status_str(PLX_STATUS_INTERNAL)) != 0);
    CHECK(strcmp(plx_status_str(12345), "unknown status") == 0);

#ifdef PLX_TEST_HOOKS
    /* A panic inside the library becomes a status and a message, and the scene stays usable. */
    CHECK_STATUS(scene, plx_test_panic(scene), PLX_STATUS_PANIC);
    CHECK_MESSAGE(scene, "plx_test_panic was called");
    CHECK_STATUS(scene, plx_scene_set_stereo_pair(scene, &ok, &ok), PLX_STATUS_OK);
#endif

    /* After all those failures the scene still accepts a valid pair. */
    CHECK_STATUS(scene, plx_scene_set_stereo_pair(scene, &ok, &ok), PLX_STATUS_OK);
    plx_scene_free(scene);
    plx_context_free(ctx);
    TEST_EXIT();
}
