/* The host's lighting replaces the estimates: lights, SH9 and an environment map, with every
 * validation error named, and the values read back exactly. */
#include <math.h>
#include <stdlib.h>

#include "check.h"

enum { W = 96, H = 64, SHIFT = 6 };

/* A random texture, brighter on the left: a wall seen from different points looks different. */
static uint8_t texel(long x, long y) {
    unsigned long long v = (unsigned long long)(x * 73856093L) ^ (unsigned long long)(y * 19349663L);
    v ^= v >> 13;
    v *= 0x5bd1e995ull;
    return (uint8_t)((v >> 24) % 128 + (x < W / 2 ? 120 : 0));
}

static float max_abs_diff(const float *a, const float *b, int n) {
    float m = 0;
    for (int i = 0; i < n; i++) {
        float d = a[i] > b[i] ? a[i] - b[i] : b[i] - a[i];
        if (d > m) m = d;
    }
    return m;
}

int main(void) {
    plx_context *ctx = NULL;
    CHECK_STATUS(NULL, plx_context_new(NULL, &ctx), PLX_STATUS_OK);
    plx_scene *scene = NULL;
    CHECK_STATUS(ctx, plx_scene_new(ctx, &scene), PLX_STATUS_OK);

    /* Without a photo there is nothing to estimate from. */
    size_t count = 99;
    CHECK_STATUS(scene, plx_scene_lights(scene, NULL, 0, &count), PLX_STATUS_NOT_AVAILABLE);
    CHECK(count == 99);

    plx_light lights[2] = {
        {PLX_LIGHT_KIND_DIRECTIONAL, {0, 0, 0}, {0, -1, 0}, 0.5f, {2, 2, 2}, 1},
        {PLX_LIGHT_KIND_AREA, {0.5f, 2.5f, -2}, {0, -1, 0}, 0.4f, {8, 7, 6}, 0.8f},
    };
    CHECK_STATUS(scene, plx_scene_set_lights(scene, lights, 2), PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_scene_lights(scene, NULL, 0, &count), PLX_STATUS_OK);
    CHECK(count == 2);
    plx_light back[3];
    memset(back, 0, sizeof back);
    CHECK_STATUS(scene, plx_scene_lights(scene, back, 1, &count), PLX_STATUS_OK);
    CHECK(count == 2);
    CHECK(back[0].kind == PLX_LIGHT_KIND_DIRECTIONAL && back[0].size == 0.5f);
    CHECK(back[1].kind == 0 && back[1].intensity[0] == 0); /* capacity 1: untouched */
    CHECK_STATUS(scene, plx_scene_lights(scene, back, 3, &count), PLX_STATUS_OK);
    CHECK(back[1].kind == PLX_LIGHT_KIND_AREA && back[1].intensity[1] == 7 &&
          back[1].position[1] == 2.5f);

    /* The main light is the brightest; its direction points towards it. */
    float dir[3], rgb[3];
    CHECK_STATUS(scene, plx_scene_main_light(scene, dir, rgb), PLX_STATUS_OK);
    CHECK(rgb[0] == 8 && rgb[1] == 7 && rgb[2] == 6);
    CHECK(dir[1] > 0.7f);
    /* Seen from 2 m in front of the camera without an insertion point (the lamp is 0.5 m to the
     * right of it), from the insertion point with one (straight under the lamp). */
    CHECK(fabsf(dir[0] - 0.5f / sqrtf(6.5f)) < 1e-4f && fabsf(dir[2]) < 1e-4f);
    const float under_lamp[3] = {0.5f, 0.0f, -2.0f};
    CHECK_STATUS(scene, plx_scene_set_insertion_point(scene, under_lamp), PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_scene_main_light(scene, dir, rgb), PLX_STATUS_OK);
    CHECK(fabsf(dir[0]) < 1e-4f && dir[1] > 0.9999f);
    CHECK_STATUS(scene, plx_scene_set_insertion_point(scene, NULL), PLX_STATUS_OK);

    /* Bad lights are refused by name and leave the scene unchanged. */
    plx_light bad = lights[0];
    bad.intensity[1] = -1;
    CHECK_STATUS(scene, plx_scene_set_lights(scene, &bad, 1), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "intensity");
    bad = lights[0];
    bad.kind = 7;
    CHECK_STATUS(scene, plx_scene_set_lights(scene, &bad, 1), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "light kind");
    bad = lights[0];
    bad.direction[0] = bad.direction[1] = bad.direction[2] = 0;
    CHECK_STATUS(scene, plx_scene_set_lights(scene, &bad, 1), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "direction");
    CHECK_STATUS(scene, plx_scene_set_lights(scene, NULL, 1), PLX_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(scene, plx_scene_lights(scene, NULL, 0, &count), PLX_STATUS_OK);
    CHECK(count == 2);

    /* An empty list: no direct light at all. */
    CHECK_STATUS(scene, plx_scene_set_lights(scene, NULL, 0), PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_scene_lights(scene, NULL, 0, &count), PLX_STATUS_OK);
    CHECK(count == 0);
    CHECK_STATUS(scene, plx_scene_main_light(scene, dir, rgb), PLX_STATUS_OK);
    CHECK(rgb[0] == 0 && dir[0] == 0 && dir[1] == 0);
    CHECK_STATUS(scene, plx_scene_reset_lights(scene), PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_scene_lights(scene, NULL, 0, &count), PLX_STATUS_NOT_AVAILABLE);

    /* SH9 round trip; a NaN coefficient is refused. */
    float sh[27], sh_back[27];
    for (int i = 0; i < 27; i++) sh[i] = 0.01f * (float)i;
    CHECK_STATUS(scene, plx_scene_set_sh9(scene, sh), PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_scene_sh9(scene, sh_back), PLX_STATUS_OK);
    CHECK(memcmp(sh, sh_back, sizeof sh) == 0);
    sh[5] = 0.0f / 0.0f;
    CHECK_STATUS(scene, plx_scene_set_sh9(scene, sh), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "coefficient 5");
    CHECK_STATUS(scene, plx_scene_sh9(scene, NULL), PLX_STATUS_NULL_ARGUMENT);

    /* An environment map: the SH then comes from it (constant radiance 0.5 gives 0.5 diffuse
     * radiance: only the first coefficient is non-zero). */
    CHECK_STATUS(scene, plx_scene_set_sh9(scene, NULL), PLX_STATUS_OK);
    float env[8 * 16 * 3];
    for (int i = 0; i < 8 * 16 * 3; i++) env[i] = 0.5f;
    plx_image image = {(const uint8_t *)env, 16, 8, 16 * 3 * sizeof(float), PLX_PIXEL_FORMAT_RGB_F32};
    CHECK_STATUS(scene, plx_scene_set_environment_equirect(scene, &image), PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_scene_sh9(scene, sh_back), PLX_STATUS_OK);
    for (int c = 0; c < 3; c++) CHECK(sh_back[c] > 0.45f && sh_back[c] < 0.55f);
    for (int i = 3; i < 27; i++) CHECK(sh_back[i] > -0.02f && sh_back[i] < 0.02f);
    image.width = 8; /* not 2:1 */
    CHECK_STATUS(scene, plx_scene_set_environment_equirect(scene, &image), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "twice as wide");
    image.width = 16;
    /* NaN, negative and infinite texels are read as 0, 0 and the largest float: finite SH. */
    env[6] = 0.0f / 0.0f;
    env[7] = -1.0f;
    env[8] = 1.0f / 0.0f;
    CHECK_STATUS(scene, plx_scene_set_environment_equirect(scene, &image), PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_scene_sh9(scene, sh_back), PLX_STATUS_OK);
    for (int i = 0; i < 27; i++) CHECK(sh_back[i] == sh_back[i] && sh_back[i] < 1e6f && sh_back[i] > -1e6f);
    /* The cube of a constant map is that constant on every face, in any float layout. */
    for (int i = 0; i < 8 * 16 * 3; i++) env[i] = 0.5f;
    CHECK_STATUS(scene, plx_scene_set_environment_equirect(scene, &image), PLX_STATUS_OK);
    uint32_t face_size = 0;
    CHECK_STATUS(scene, plx_scene_environment_cube_size(scene, &face_size), PLX_STATUS_OK);
    CHECK(face_size >= 4 && face_size <= 1024);
    float *face = malloc((size_t)face_size * face_size * 4 * sizeof(float));
    CHECK(face != NULL);
    plx_image_out face_out = {(uint8_t *)face, face_size, face_size, face_size * 4 * sizeof(float),
                              PLX_PIXEL_FORMAT_RGBA_F32};
    for (uint32_t f = 0; f < 6; f++) {
        CHECK_STATUS(scene, plx_scene_environment_cube_face(scene, f, &face_out), PLX_STATUS_OK);
        for (uint32_t i = 0; i < face_size * face_size; i++) {
            CHECK(face[i * 4] > 0.45f && face[i * 4] < 0.55f);
            CHECK(face[i * 4 + 3] == 1.0f);
        }
    }
    CHECK_STATUS(scene, plx_scene_environment_cube_face(scene, 6, &face_out), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "cube face 6");
    face_out.width = face_size + 1;
    CHECK_STATUS(scene, plx_scene_environment_cube_face(scene, 0, &face_out), PLX_STATUS_SIZE_MISMATCH);
    CHECK_STATUS(scene, plx_scene_environment_cube_face(scene, 0, NULL), PLX_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(scene, plx_scene_environment_cube_size(scene, NULL), PLX_STATUS_NULL_ARGUMENT);
    free(face);
    CHECK_STATUS(scene, plx_scene_set_environment_equirect(scene, NULL), PLX_STATUS_OK);

    /* The estimated environment is built around the insertion point the host names: a wall
     * brighter on its left half lights a point near its left half differently. NULL goes back to
     * the default point; a NaN coordinate is refused and changes nothing. */
    static uint8_t left[W * H], right[W * H];
    for (long y = 0; y < H; y++)
        for (long x = 0; x < W; x++) {
            left[y * W + x] = texel(x, y);
            right[y * W + x] = texel(x + SHIFT, y);
        }
    plx_image l = {left, W, H, W, PLX_PIXEL_FORMAT_GRAY8};
    plx_image r = {right, W, H, W, PLX_PIXEL_FORMAT_GRAY8};
    CHECK_STATUS(scene, plx_scene_set_stereo_pair(scene, &l, &r), PLX_STATUS_OK);
    plx_calibration calib = {100.0, W / 2.0, H / 2.0, 0.12, 0.0, 16};
    CHECK_STATUS(scene, plx_scene_set_calibration(scene, &calib), PLX_STATUS_OK);
    float sh_default[27], sh_left[27], sh_right[27];
    CHECK_STATUS(scene, plx_scene_sh9(scene, sh_default), PLX_STATUS_OK);
    /* The wall is 2 m away (f·B/d = 100 · 0.12 / 6); stand 0.3 m in front of it. */
    const float at_left[3] = {-0.6f, 0.0f, -1.7f}, at_right[3] = {0.6f, 0.0f, -1.7f};
    CHECK_STATUS(scene, plx_scene_set_insertion_point(scene, at_left), PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_scene_sh9(scene, sh_left), PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_scene_set_insertion_point(scene, at_right), PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_scene_sh9(scene, sh_right), PLX_STATUS_OK);
    CHECK(sh_left[0] > sh_right[0] + 0.02f);
    const float bad_point[3] = {0.0f, 0.0f / 0.0f, -1.0f};
    CHECK_STATUS(scene, plx_scene_set_insertion_point(scene, bad_point), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "insertion point");
    CHECK_STATUS(scene, plx_scene_sh9(scene, sh_back), PLX_STATUS_OK);
    CHECK(max_abs_diff(sh_back, sh_right, 27) == 0.0f);
    CHECK_STATUS(scene, plx_scene_set_insertion_point(scene, NULL), PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_scene_sh9(scene, sh_back), PLX_STATUS_OK);
    CHECK(max_abs_diff(sh_back, sh_default, 27) == 0.0f);

    plx_scene_free(scene);

    /* A host with its own depth gives the photo alone: lights and the photo work on it, stereo
     * has nothing to match and says so. */
    CHECK_STATUS(ctx, plx_scene_new(ctx, &scene), PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_scene_set_photo(scene, NULL), PLX_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(scene, plx_scene_set_photo(scene, &l), PLX_STATUS_OK);
    static float floor_depth[W * H];
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) /* a floor 1 m below the camera, a wall at 5 m */
            floor_depth[y * W + x] = y > H / 2 ? fminf(100.0f / ((float)y + 0.5f - H / 2.0f), 5.0f) : 5.0f;
    plx_camera cam = {100.0f, 100.0f, W / 2.0f, H / 2.0f};
    CHECK_STATUS(scene, plx_scene_set_depth(scene, floor_depth, W, H, W * 4, NULL, 0, &cam),
                 PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_scene_sh9(scene, sh_back), PLX_STATUS_OK);
    for (int i = 0; i < 27; i++) CHECK(sh_back[i] == sh_back[i]);
    CHECK(sh_back[0] > 0.0f);
    uint32_t pw = 0, ph = 0;
    CHECK_STATUS(scene, plx_scene_photo_size(scene, &pw, &ph), PLX_STATUS_OK);
    CHECK(pw == W && ph == H);
    plx_float_view disparity;
    CHECK_STATUS(scene, plx_scene_disparity(scene, &disparity), PLX_STATUS_NOT_AVAILABLE);
    CHECK_MESSAGE(scene, "set_photo");
    plx_image small = {left, W / 2, H, W, PLX_PIXEL_FORMAT_GRAY8};
    CHECK_STATUS(scene, plx_scene_set_photo(scene, &small), PLX_STATUS_SIZE_MISMATCH);
    plx_scene_free(scene);
    plx_context_free(ctx);
    TEST_EXIT();
}
