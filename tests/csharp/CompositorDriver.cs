// Drives ParallaxCompositor (bindings/unity) under Mono with the UnityEngine stand-in: builds the
// two textures from raw top-down RGBA8 files as Unity would hold them (bottom-up), composes, and
// writes the output texture's pixels as raw RGBA8 in Unity's order (bottom row first).
//
//   mono compositor_driver.exe LEFT.rgba RIGHT.rgba WIDTH HEIGHT MODEL.glb FOCAL_PX BASELINE_M X Y OUT.rgba
using System;
using System.Globalization;
using System.IO;
using Parallax;
using UnityEngine;

static class CompositorDriver
{
    static Texture2D Load(string path, int w, int h)
    {
        byte[] rgba = File.ReadAllBytes(path);
        Color32[] pixels = new Color32[w * h];
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++)
            {
                int s = 4 * (y * w + x);
                pixels[(h - 1 - y) * w + x] = new Color32(rgba[s], rgba[s + 1], rgba[s + 2], rgba[s + 3]);
            }
        Texture2D t = new Texture2D(w, h, TextureFormat.RGBA32, false);
        t.SetPixels32(pixels);
        return t;
    }

    static int Main(string[] a)
    {
        CultureInfo c = CultureInfo.InvariantCulture;
        int w = int.Parse(a[2], c), h = int.Parse(a[3], c);
        ParallaxCompositor compositor = new ParallaxCompositor();
        compositor.left = Load(a[0], w, h);
        compositor.right = Load(a[1], w, h);
        compositor.focalPx = float.Parse(a[5], c);
        compositor.baselineM = float.Parse(a[6], c);
        ArtefactPlacement p = new ArtefactPlacement();
        p.gltfPath = a[4];
        p.pixel = new Vector2(float.Parse(a[7], c), float.Parse(a[8], c));
        p.sizeM = 0.3f;
        p.yawDeg = 30;
        compositor.artefacts.Add(p);
        if (!compositor.Compose())
            return 1;
        // A second composition moves nothing but must not add a second box.
        if (!compositor.Compose())
            return 1;
        Color32[] output = compositor.output.GetPixels32();
        byte[] raw = new byte[output.Length * 4];
        for (int i = 0; i < output.Length; i++)
        {
            raw[4 * i] = output[i].r;
            raw[4 * i + 1] = output[i].g;
            raw[4 * i + 2] = output[i].b;
            raw[4 * i + 3] = output[i].a;
        }
        File.WriteAllBytes(a[9], raw);
        Console.WriteLine("output_size=" + compositor.output.width + "x" + compositor.output.height);
        Console.WriteLine("applied=" + compositor.output.applied);
        Console.WriteLine("errors_logged=" + UnityEngine.Debug.errors);
        // The device's gravity (level camera) replaces the planes' up.
        compositor.gravityUp = new Vector3(0, 1, 0);
        Console.WriteLine("gravity_composed=" + (compositor.Compose() ? 1 : 0));
        // A missing model is logged with its status, and Compose reports failure.
        p.gltfPath = Path.Combine(Path.GetDirectoryName(a[9]), "missing.glb");
        Console.WriteLine("missing_model_composed=" + (compositor.Compose() ? 1 : 0));
        Console.WriteLine("errors_logged_after=" + UnityEngine.Debug.errors);
        return 0;
    }
}
