/* Artefacts through the C API: a box built here as GLB bytes (JSON chunk + BIN chunk by hand) is
 * added, instanced, moved, flagged, placed on an analytic floor and removed; unknown ids, bad
 * transforms and broken input fail with the right status. With PARALLAX_DATA set (tests/ffi.rs
 * sets it when the shared data exists), every broken file of its gltf/ folder fails with its
 * status and a message, and valid ones load. */
#include <math.h>
#include <stdint.h>

#include "check.h"
/* after check.h: it uses CHECK */
#include "box_glb.h"

static int near3(const float *a, const float *b, float tol) {
    return fabsf(a[0] - b[0]) <= tol && fabsf(a[1] - b[1]) <= tol && fabsf(a[2] - b[2]) <= tol;
}

static void identity(float m[16]) {
    memset(m, 0, 16 * sizeof(float));
    m[0] = m[5] = m[10] = m[15] = 1.0f;
}

/* Floor 1 m below the camera and a wall 6 m ahead (as in mesh.c). */
enum { W = 64, H = 48 };
static const float F = 60.0f;
static float floor_depth(int y) {
    float dy = -((y + 0.5f) - H / 2.0f) / F;
    float t = 6.0f;
    if (dy < 0.0f && -1.0f / dy < t) t = -1.0f / dy;
    return t;
}

static char *join(const char *dir, const char *file) {
    static char buf[4096];
    snprintf(buf, sizeof buf, "%s/gltf/%s", dir, file);
    return buf;
}

static void shared_files(plx_scene *scene, const char *dir) {
    static const struct {
        const char *file;
        plx_status status;
        const char *needle;
    } broken[] = {
        {"RecursiveNodes/RecursiveNodes.gltf", PLX_STATUS_FORMAT, "cycle"},
        {"IndexOutOfRange/IndexOutOfRange.gltf", PLX_STATUS_FORMAT, "out of range"},
        {"IndexOutOfRange/AllIndicesOutOfRange.gltf", PLX_STATUS_FORMAT, "out of range"},
        {"IncorrectVertexArrays/Cube.gltf", PLX_STATUS_FORMAT, "not a multiple of 3"},
        {"MissingBin/BoxTextured.gltf", PLX_STATUS_IO, "BoxTextured0.bin"},
        {"SchemaFailures/sceneWrongType.gltf", PLX_STATUS_FORMAT, "hello"},
        {"wrongTypes/badArray.gltf", PLX_STATUS_FORMAT, "sequence"},
        {"wrongTypes/badExtension.gltf", PLX_STATUS_FORMAT, "TextureTransform"},
        {"wrongTypes/badNumber.gltf", PLX_STATUS_FORMAT, "number"},
        {"wrongTypes/badObject.gltf", PLX_STATUS_FORMAT, "object"},
        {"wrongTypes/badString.gltf", PLX_STATUS_FORMAT, "string"},
        {"wrongTypes/badUint.gltf", PLX_STATUS_FORMAT, "-1"},
        {"BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb", PLX_STATUS_FORMAT, "not finite"},
        {"draco/2CylinderEngine.gltf", PLX_STATUS_UNSUPPORTED, "KHR_draco_mesh_compression"},
        {"BoxTextured-glTF-techniqueWebGL/BoxTextured.gltf", PLX_STATUS_UNSUPPORTED,
         "KHR_technique_webgl"},
        {"no/such/file.glb", PLX_STATUS_IO, "file.glb"},
    };
    uint32_t id = 12345;
    for (size_t i = 0; i < sizeof broken / sizeof broken[0]; i++) {
        const char *path = join(dir, broken[i].file);
        plx_status got = plx_scene_add_artefact_path(scene, path, NULL, &id);
        char msg[1024];
        size_t needed = 0;
        plx_last_error_message(scene, msg, sizeof msg, &needed);
        if (got != broken[i].status || needed <= 1 || strstr(msg, broken[i].needle) == NULL) {
            fprintf(stderr, "%s: status %d (expected %d), message \"%s\" (expected \"%s\")\n",
                    broken[i].file, (int)got, (int)broken[i].status, msg, broken[i].needle);
            plx_failures++;
        }
        CHECK(id == 12345); /* outputs untouched on error */
    }

    /* Valid ones: the textured box in its three encodings (12 triangles, a 1 m cube). */
    static const char *valid[] = {"BoxTextured-glTF/BoxTextured.gltf",
                                  "BoxTextured-glTF-Binary/BoxTextured.glb",
                                  "BoxTextured-glTF-Embedded/BoxTextured.gltf"};
    const float lo[3] = {-0.5f, -0.5f, -0.5f}, hi[3] = {0.5f, 0.5f, 0.5f};
    for (size_t i = 0; i < 3; i++) {
        CHECK_STATUS(scene, plx_scene_add_artefact_path(scene, join(dir, valid[i]), NULL, &id),
                     PLX_STATUS_OK);
        float a[3], b[3];
        CHECK_STATUS(scene, plx_artefact_bounds(scene, id, a, b, NULL, NULL), PLX_STATUS_OK);
        CHECK(near3(a, lo, 1e-5f) && near3(b, hi, 1e-5f));
        CHECK_STATUS(scene, plx_scene_remove_artefact(scene, id), PLX_STATUS_OK);
    }
    /* A repaired file loads with warnings; a file without geometry has empty bounds and cannot be
     * placed by size. */
    CHECK_STATUS(scene,
                 plx_scene_add_artefact_path(
                     scene, join(dir, "BoxBadNormals-glTF-Binary/BoxBadNormals.glb"), NULL, &id),
                 PLX_STATUS_OK);
    size_t count = 0;
    char warnings[2048];
    CHECK_STATUS(scene,
                 plx_scene_artefact_warnings(scene, id, warnings, sizeof warnings, NULL, &count),
                 PLX_STATUS_OK);
    CHECK(count > 0 && strstr(warnings, "recomputed") != NULL);
    CHECK_STATUS(scene, plx_scene_remove_artefact(scene, id), PLX_STATUS_OK);
    CHECK_STATUS(scene,
                 plx_scene_add_artefact_path(scene, join(dir, "TestNoRootNode/NoScene.gltf"),
                                             NULL, &id),
                 PLX_STATUS_OK);
    float a[3] = {1, 1, 1}, b[3] = {1, 1, 1};
    const float zero[3] = {0, 0, 0};
    CHECK_STATUS(scene, plx_artefact_bounds(scene, id, a, b, NULL, NULL), PLX_STATUS_OK);
    CHECK(near3(a, zero, 0) && near3(b, zero, 0));
    CHECK_STATUS(scene, plx_scene_place_artefact(scene, id, 32.5f, 40.5f, 0.5f, 0.0f, NULL),
                 PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "no extent");
    CHECK_STATUS(scene, plx_scene_remove_artefact(scene, id), PLX_STATUS_OK);

    /* A valid GLB file read into memory loads from memory too. */
    FILE *f = fopen(join(dir, "BoxTextured-glTF-Binary/BoxTextured.glb"), "rb");
    CHECK(f != NULL);
    if (f) {
        static uint8_t bytes[1 << 20];
        size_t len = fread(bytes, 1, sizeof bytes, f);
        fclose(f);
        CHECK(len > 0 && len < sizeof bytes);
        CHECK_STATUS(scene, plx_scene_add_artefact_memory(scene, bytes, len, NULL, &id),
                     PLX_STATUS_OK);
        CHECK_STATUS(scene, plx_artefact_bounds(scene, id, a, b, NULL, NULL), PLX_STATUS_OK);
        CHECK(near3(a, lo, 1e-5f) && near3(b, hi, 1e-5f));
        CHECK_STATUS(scene, plx_scene_remove_artefact(scene, id), PLX_STATUS_OK);
    }
}

int main(void) {
    static uint8_t glb[2048];
    size_t len = box_glb(glb, NULL);

    plx_context *ctx = NULL;
    plx_scene *scene = NULL;
    CHECK_STATUS(NULL, plx_context_new(NULL, &ctx), PLX_STATUS_OK);
    CHECK_STATUS(ctx, plx_scene_new(ctx, &scene), PLX_STATUS_OK);

    /* Add from memory with the identity (NULL transform): world = local = the box. A build
     * without glTF support answers UNSUPPORTED to every artefact function. */
    uint32_t a = 99, b = 99;
    plx_status added = plx_scene_add_artefact_memory(scene, glb, len, NULL, &a);
    if (added == PLX_STATUS_UNSUPPORTED) {
        CHECK_MESSAGE(scene, "gltf");
        CHECK_STATUS(scene, plx_scene_add_artefact_path(scene, "x.glb", NULL, &a),
                     PLX_STATUS_UNSUPPORTED);
        CHECK_STATUS(scene, plx_scene_remove_artefact(scene, 0), PLX_STATUS_UNSUPPORTED);
        CHECK_STATUS(scene, plx_artefact_bounds(scene, 0, NULL, NULL, NULL, NULL),
                     PLX_STATUS_UNSUPPORTED);
        CHECK(a == 99);
        plx_scene_free(scene);
        plx_context_free(ctx);
        TEST_EXIT();
    }
    CHECK_STATUS(scene, added, PLX_STATUS_OK);
    float lmin[3], lmax[3], wmin[3], wmax[3];
    CHECK_STATUS(scene, plx_artefact_bounds(scene, a, lmin, lmax, wmin, wmax), PLX_STATUS_OK);
    CHECK(near3(lmin, BOX_MIN, 0) && near3(lmax, BOX_MAX, 0));
    CHECK(near3(wmin, BOX_MIN, 0) && near3(wmax, BOX_MAX, 0));

    /* The loader generated the missing normals and says so; the report names the load. */
    size_t count = 0, needed = 0;
    char text[8192];
    CHECK_STATUS(scene, plx_scene_artefact_warnings(scene, a, text, sizeof text, &needed, &count),
                 PLX_STATUS_OK);
    CHECK(count >= 1 && needed == strlen(text) + 1 && strstr(text, "normal") != NULL);
    char tiny[4];
    CHECK_STATUS(scene, plx_scene_artefact_warnings(scene, a, tiny, sizeof tiny, &needed, NULL),
                 PLX_STATUS_OK);
    CHECK(strlen(tiny) == 3 && needed > sizeof tiny);
    CHECK_STATUS(scene, plx_scene_artefact_warnings(scene, a, NULL, 4, NULL, NULL),
                 PLX_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(scene, plx_scene_report(scene, text, sizeof text, NULL), PLX_STATUS_OK);
    CHECK(strstr(text, "artefact.load") != NULL && strstr(text, "normal") != NULL);

    /* A second instance, translated by (2, -1, -3) (column-major: elements 12..14). */
    float m[16];
    identity(m);
    m[12] = 2.0f, m[13] = -1.0f, m[14] = -3.0f;
    CHECK_STATUS(scene, plx_scene_add_artefact_memory(scene, glb, len, m, &b), PLX_STATUS_OK);
    CHECK(b != a);
    CHECK_STATUS(scene, plx_artefact_bounds(scene, b, lmin, lmax, wmin, wmax), PLX_STATUS_OK);
    const float t_min[3] = {1.0f, -1.0f, -3.5f}, t_max[3] = {3.0f, -0.5f, -2.5f};
    CHECK(near3(lmin, BOX_MIN, 0) && near3(lmax, BOX_MAX, 0));
    CHECK(near3(wmin, t_min, 1e-6f) && near3(wmax, t_max, 1e-6f));

    /* Move the first: a quarter turn about +Y (x -> -z, z -> x), scaled by 2. */
    float r[16];
    identity(r);
    r[0] = 0.0f, r[2] = -2.0f; /* column 0: image of +X = (0, 0, -2) */
    r[5] = 2.0f;
    r[8] = 2.0f, r[10] = 0.0f; /* column 2: image of +Z = (2, 0, 0) */
    CHECK_STATUS(scene, plx_scene_set_artefact_transform(scene, a, r), PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_artefact_bounds(scene, a, NULL, NULL, wmin, wmax), PLX_STATUS_OK);
    const float r_min[3] = {-1.0f, 0.0f, -2.0f}, r_max[3] = {1.0f, 1.0f, 2.0f};
    CHECK(near3(wmin, r_min, 1e-6f) && near3(wmax, r_max, 1e-6f));

    /* Bad transforms change nothing. */
    float bad[16];
    identity(bad);
    bad[13] = NAN;
    CHECK_STATUS(scene, plx_scene_set_artefact_transform(scene, a, bad),
                 PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "non-finite");
    bad[13] = INFINITY;
    uint32_t unchanged = 77;
    CHECK_STATUS(scene, plx_scene_add_artefact_memory(scene, glb, len, bad, &unchanged),
                 PLX_STATUS_INVALID_ARGUMENT);
    CHECK(unchanged == 77);
    CHECK_STATUS(scene, plx_scene_set_artefact_transform(scene, a, NULL), PLX_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(scene, plx_artefact_bounds(scene, a, NULL, NULL, wmin, wmax), PLX_STATUS_OK);
    CHECK(near3(wmin, r_min, 1e-6f) && near3(wmax, r_max, 1e-6f));

    /* Flags. */
    CHECK_STATUS(scene, plx_scene_set_artefact_flags(scene, a, 0, 1, 0), PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_scene_set_artefact_flags(scene, a, 2, 1, 1),
                 PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "visible");
    CHECK_STATUS(scene, plx_scene_set_artefact_flags(scene, a, 1, 1, 7),
                 PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "receives_shadow");

    /* Broken input from memory. */
    uint32_t id = 55;
    CHECK_STATUS(scene, plx_scene_add_artefact_memory(scene, glb, len / 2, NULL, &id),
                 PLX_STATUS_FORMAT);
    CHECK_STATUS(scene, plx_scene_add_artefact_memory(scene, (const uint8_t *)"hello", 5, NULL, &id),
                 PLX_STATUS_FORMAT);
    CHECK_STATUS(scene, plx_scene_add_artefact_memory(scene, NULL, 0, NULL, &id), PLX_STATUS_FORMAT);
    {
        static uint8_t external[2048];
        size_t n = box_glb(external, "box.bin");
        CHECK_STATUS(scene, plx_scene_add_artefact_memory(scene, external, n, NULL, &id),
                     PLX_STATUS_INVALID_ARGUMENT);
        CHECK_MESSAGE(scene, "box.bin");
    }
    CHECK(id == 55);
    CHECK_STATUS(scene, plx_scene_add_artefact_memory(scene, NULL, 10, NULL, &id),
                 PLX_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(scene, plx_scene_add_artefact_memory(scene, glb, len, NULL, NULL),
                 PLX_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(scene, plx_scene_add_artefact_path(scene, NULL, NULL, &id),
                 PLX_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(scene, plx_scene_add_artefact_path(scene, "/no/such/dir/box.glb", NULL, &id),
                 PLX_STATUS_IO);
    CHECK_MESSAGE(scene, "box.glb");
    CHECK_STATUS(NULL, plx_scene_add_artefact_memory(NULL, glb, len, NULL, &id),
                 PLX_STATUS_NULL_ARGUMENT);

    /* Placement needs depth; then the box stands on the floor, largest side 0.5 m. */
    CHECK_STATUS(scene, plx_scene_place_artefact(scene, b, 32.5f, 40.5f, 0.5f, 0.0f, NULL),
                 PLX_STATUS_NOT_AVAILABLE);
    static float depth[W * H];
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) depth[y * W + x] = floor_depth(y);
    plx_camera cam = {F, F, W / 2.0f, H / 2.0f};
    CHECK_STATUS(scene, plx_scene_set_depth(scene, depth, W, H, W * 4, NULL, 0, &cam),
                 PLX_STATUS_OK);
    float placed[16];
    CHECK_STATUS(scene, plx_scene_place_artefact(scene, b, 32.5f, 40.5f, 0.5f, 30.0f, placed),
                 PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_artefact_bounds(scene, b, NULL, NULL, wmin, wmax), PLX_STATUS_OK);
    CHECK(fabsf(wmin[1] + 1.0f) < 0.01f);
    CHECK(fabsf(wmax[1] - wmin[1] - 0.125f) < 2e-3f); /* 0.5 m tall box scaled by 0.25 */
    CHECK(fabsf(placed[13] - wmin[1]) < 1e-4f);      /* the base point is the translation */
    CHECK_STATUS(scene, plx_scene_place_artefact(scene, b, -100.0f, 10.0f, 0.5f, 0.0f, NULL),
                 PLX_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(scene, plx_scene_place_artefact(scene, b, 32.5f, 40.5f, 0.0f, 0.0f, NULL),
                 PLX_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(scene, plx_scene_place_artefact(scene, b, 32.5f, 40.5f, 0.5f, NAN, NULL),
                 PLX_STATUS_INVALID_ARGUMENT);

    /* Removal and unknown ids (each message names the id). */
    CHECK_STATUS(scene, plx_scene_remove_artefact(scene, a), PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_scene_remove_artefact(scene, a), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "id 0");
    CHECK_STATUS(scene, plx_artefact_bounds(scene, 999, lmin, lmax, wmin, wmax),
                 PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "999");
    CHECK_STATUS(scene, plx_scene_set_artefact_transform(scene, 999, m),
                 PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "999");
    CHECK_STATUS(scene, plx_scene_set_artefact_flags(scene, 999, 1, 1, 1),
                 PLX_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(scene, plx_scene_place_artefact(scene, 999, 32.5f, 40.5f, 0.5f, 0.0f, NULL),
                 PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "999");
    CHECK_STATUS(scene, plx_scene_artefact_warnings(scene, 999, NULL, 0, NULL, NULL),
                 PLX_STATUS_INVALID_ARGUMENT);
    /* A new artefact gets a new id, never a removed one. */
    uint32_t c = 0;
    CHECK_STATUS(scene, plx_scene_add_artefact_memory(scene, glb, len, NULL, &c), PLX_STATUS_OK);
    CHECK(c != a && c != b);

    const char *data = getenv("PARALLAX_DATA");
    if (data && *data) {
        shared_files(scene, data);
    } else {
        fprintf(stderr, "artefact.c: PARALLAX_DATA not set, shared glTF files skipped\n");
    }

    plx_scene_free(scene);
    plx_context_free(ctx);
    TEST_EXIT();
}
