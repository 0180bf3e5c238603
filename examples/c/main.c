/* A C11 host of Parallax using only parallax.h: loads a stereo pair, inserts a glTF model
 * standing on the scene at a chosen pixel, renders the composite and saves it as a binary PPM
 * (and the model's coverage as a PGM next to it), printing key=value lines (read by tests/c.rs
 * and tests/packaging.rs).
 *
 *   parallax_example_c LEFT.png RIGHT.png MODEL.glb FOCAL_PX BASELINE_M X Y OUT.ppm
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "parallax.h"

/* Prints the failed call, its status and the library's message, and jumps to cleanup. */
#define TRY(handle, call)                                                                       \
    do {                                                                                        \
        plx_status status_ = (call);                                                            \
        if (status_ != PLX_STATUS_OK) {                                                         \
            char message_[512];                                                                 \
            plx_last_error_message((handle), message_, sizeof message_, NULL);                  \
            fprintf(stderr, "%s failed: %s: %s\n", #call, plx_status_str((uint32_t)status_),     \
                    message_);                                                                  \
            goto done;                                                                          \
        }                                                                                       \
    } while (0)

/* Writes `height` rows of `width × channels` bytes as PPM (3 channels) or PGM (1). */
static int save_pnm(const char *path, const uint8_t *pixels, uint32_t width, uint32_t height,
                    int channels) {
    FILE *f = fopen(path, "wb");
    if (!f) return 0;
    fprintf(f, "%s\n%u %u\n255\n", channels == 3 ? "P6" : "P5", (unsigned)width, (unsigned)height);
    size_t n = (size_t)width * height * (size_t)channels;
    int ok = fwrite(pixels, 1, n, f) == n;
    return fclose(f) == 0 && ok;
}

int main(int argc, char **argv) {
    if (argc != 9) {
        fprintf(stderr, "usage: %s LEFT RIGHT MODEL.glb FOCAL_PX BASELINE_M X Y OUT.ppm\n",
                argv[0]);
        return 2;
    }
    int rc = 1;
    plx_context *ctx = NULL;
    plx_scene *scene = NULL;
    uint8_t *rgb = NULL, *mask = NULL;
    char *mask_path = NULL;

    TRY(NULL, plx_context_new(NULL, &ctx));
    TRY(ctx, plx_scene_new(ctx, &scene));
    TRY(scene, plx_scene_load_stereo_pair(scene, argv[1], argv[2]));
    uint32_t w = 0, h = 0;
    TRY(scene, plx_scene_photo_size(scene, &w, &h));
    printf("size=%ux%u\n", (unsigned)w, (unsigned)h);

    plx_calibration calibration = {0};
    calibration.focal_px = atof(argv[4]);
    calibration.baseline_m = atof(argv[5]);
    calibration.cx = w / 2.0;
    calibration.cy = h / 2.0;
    TRY(scene, plx_scene_set_calibration(scene, &calibration));

    /* The model stood on the surface seen at pixel (x, y), 0.3 m tall at most. */
    const float x = (float)atof(argv[6]), y = (float)atof(argv[7]);
    uint32_t id = 0;
    TRY(scene, plx_scene_add_artefact_path(scene, argv[3], NULL, &id));
    float transform[16];
    TRY(scene, plx_scene_place_artefact(scene, id, x, y, 0.3f, 30.0f, transform));
    /* The room's light is estimated around the object: it is lit from where it stands. */
    TRY(scene, plx_scene_set_insertion_point(scene, &transform[12]));
    printf("artefact_position=%.4f,%.4f,%.4f\n", transform[12], transform[13], transform[14]);

    /* The composite as RGB8 and the coverage as GRAY8, in host buffers. */
    plx_render_options options;
    TRY(NULL, plx_render_options_init(&options));
    options.shadow_map_size = 512;
    rgb = malloc((size_t)w * h * 3);
    mask = malloc((size_t)w * h);
    if (!rgb || !mask) goto done;
    plx_image_out out = {rgb, w, h, (size_t)w * 3, PLX_PIXEL_FORMAT_RGB8};
    plx_image_out mask_out = {mask, w, h, w, PLX_PIXEL_FORMAT_GRAY8};
    TRY(scene, plx_scene_render(scene, &options, &out, &mask_out));
    size_t covered = 0;
    for (size_t i = 0; i < (size_t)w * h; i++) covered += mask[i] > 127;
    printf("mask_pixels=%zu\n", covered);
    printf("mask_at_pixel=%u\n", (unsigned)mask[(size_t)y * w + (size_t)x]);

    const char *path = argv[8];
    mask_path = malloc(strlen(path) + sizeof "-mask.pgm");
    if (!mask_path) goto done;
    strcpy(mask_path, path);
    char *dot = strrchr(mask_path, '.');
    strcpy(dot ? dot : mask_path + strlen(mask_path), "-mask.pgm");
    if (!save_pnm(path, rgb, w, h, 3) || !save_pnm(mask_path, mask, w, h, 1)) {
        fprintf(stderr, "cannot write %s\n", path);
        goto done;
    }
    printf("composite=%s\n", path);
    rc = 0;

done:
    free(mask_path);
    free(mask);
    free(rgb);
    plx_scene_free(scene);
    plx_context_free(ctx);
    return rc;
}
