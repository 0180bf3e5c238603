// ParallaxCompositor: a Unity component that puts glTF objects into a stereo photo.
//
// Give it the rectified stereo pair as two readable Texture2D (Read/Write enabled in the import
// settings), the glTF files with the photo pixel each should stand on, and it fills `output` with
// the composite (the left photo with the objects lit, shadowed and hidden behind the photo's own
// geometry).
//
// Rows: Parallax images are rows top first (pixel (0, 0) is the top-left corner) and Unity
// textures are bottom-up (GetPixels32 starts with the bottom row). This component flips the rows
// on the way in and on the way out, so `output` shows the right way up, and it takes the pixel of
// each placement in Parallax's convention: x from the left edge, y from the TOP edge. A position
// in Unity's bottom-up texture coordinates converts with PixelFromTextureCoordinates.
//
// The composite runs synchronously on the calling thread (the main thread from Compose/Start).
// It needs the native library in the player (see Plugins/README.md in this package).
using System;
using System.Collections.Generic;
using UnityEngine;

namespace Parallax
{
    /// <summary>One glTF object and where it stands in the photo.</summary>
    [Serializable]
    public class ArtefactPlacement
    {
        /// <summary>A .glb or .gltf file (e.g. under Application.streamingAssetsPath).</summary>
        public string gltfPath;
        /// <summary>Photo pixel the object stands on: x from the left, y from the TOP edge.</summary>
        public Vector2 pixel;
        /// <summary>Largest side of the object, metres.</summary>
        public float sizeM = 0.3f;
        /// <summary>Turn about the up axis, degrees (0 = facing the camera).</summary>
        public float yawDeg;
    }

    /// <summary>Fills a Texture2D with the composite of a stereo photo and glTF objects.</summary>
    public class ParallaxCompositor : MonoBehaviour
    {
        /// <summary>Left view of the rectified pair (the photo); must be readable.</summary>
        public Texture2D left;
        /// <summary>Right view, same size; must be readable.</summary>
        public Texture2D right;
        /// <summary>Focal length in pixels; 0 = unknown (depth up to scale, sizes then relative).</summary>
        public float focalPx;
        /// <summary>Distance between the two cameras, metres.</summary>
        public float baselineM = 0.1f;
        /// <summary>The objects and their placements.</summary>
        public List<ArtefactPlacement> artefacts = new List<ArtefactPlacement>();
        /// <summary>Gravity "up" in the left camera's Unity frame (x right, y up, z forward), e.g.
        /// from the device's IMU; zero = estimate it from the photo's planes.</summary>
        public Vector3 gravityUp;
        /// <summary>Receives the composite; created (RGBA32, sRGB) when null or of another size.</summary>
        public Texture2D output;
        /// <summary>Run Compose() in Start.</summary>
        public bool composeOnStart = true;
        /// <summary>Forward Parallax's warnings and errors to the Unity console.</summary>
        public bool logWarnings = true;

        Context context;
        Scene scene;
        readonly List<uint> ids = new List<uint>();
        Texture2D sentLeft, sentRight;
        float sentFocal, sentBaseline;

        /// <summary>Call after changing the pixels of <see cref="left"/> or <see cref="right"/> in place:
        /// Compose sends the pair again (and Parallax reconstructs it) only when the textures were
        /// replaced or this was called; otherwise it reuses depth, mesh and lights.</summary>
        public void MarkPhotoChanged()
        {
            sentLeft = sentRight = null;
        }

        void Start()
        {
            if (composeOnStart)
                Compose();
        }

        void OnDestroy()
        {
            // The native library outlives the editor's domain reloads: leave it no callback into
            // this domain.
            if (logWarnings)
                Library.SetLogCallback(null);
            if (scene != null)
                scene.Dispose();
            if (context != null)
                context.Dispose();
            scene = null;
            context = null;
        }

        /// <summary>A pixel in Unity's bottom-up texture coordinates as Parallax's top-down pixel.</summary>
        public static Vector2 PixelFromTextureCoordinates(Vector2 unityPixel, int textureHeight)
        {
            return new Vector2(unityPixel.x, textureHeight - unityPixel.y);
        }

        /// <summary>Reconstructs the pair (only when it changed: Parallax caches the rest), places the
        /// objects and renders the composite into <see cref="output"/>. Returns false and logs
        /// the status and message when Parallax reports an error.</summary>
        public bool Compose()
        {
            if (left == null || right == null)
            {
                Debug.LogError("ParallaxCompositor: left and right textures are required");
                return false;
            }
            int w = left.width, h = left.height;
            if (right.width != w || right.height != h)
            {
                Debug.LogError("ParallaxCompositor: left is " + w + "x" + h + ", right " + right.width + "x" + right.height);
                return false;
            }
            try
            {
                if (logWarnings)
                    Library.SetLogCallback(Forward, PlxLogLevel.Warn);
                if (context == null)
                    context = new Context();
                if (scene == null)
                    scene = new Scene(context);
                if (left != sentLeft || right != sentRight)
                {
                    sentLeft = sentRight = null;
                    scene.SetStereoPair(TopDownRgba(left.GetPixels32(), w, h), TopDownRgba(right.GetPixels32(), w, h),
                                        w, h, PlxPixelFormat.Rgba8);
                    sentLeft = left;
                    sentRight = right;
                    sentFocal = 0;
                }
                if (focalPx > 0 && (focalPx != sentFocal || baselineM != sentBaseline))
                {
                    scene.SetCalibration(focalPx, baselineM);
                    sentFocal = focalPx;
                    sentBaseline = baselineM;
                }
                // Unity's camera looks along +z, Parallax's along -z.
                scene.SetUp(gravityUp.x == 0 && gravityUp.y == 0 && gravityUp.z == 0
                                ? null
                                : new float[] { gravityUp.x, gravityUp.y, -gravityUp.z });
                foreach (uint id in ids)
                    scene.RemoveArtefact(id);
                ids.Clear();
                for (int i = 0; i < artefacts.Count; i++)
                {
                    ArtefactPlacement a = artefacts[i];
                    uint id = scene.AddArtefactPath(a.gltfPath);
                    ids.Add(id);
                    float[] m = scene.PlaceArtefact(id, a.pixel.x, a.pixel.y, a.sizeM, a.yawDeg);
                    // The room's light is estimated around the first object (re-estimated only
                    // when it moves).
                    if (i == 0)
                        scene.SetInsertionPoint(new float[] { m[12], m[13], m[14] });
                }
                byte[] rgba = new byte[w * h * 4];
                scene.Render(rgba, w, h, PlxPixelFormat.Rgba8);
                if (output == null || output.width != w || output.height != h)
                    output = new Texture2D(w, h, TextureFormat.RGBA32, false);
                output.SetPixels32(BottomUpColors(rgba, w, h));
                output.Apply();
                return true;
            }
            catch (ParallaxException e)
            {
                Debug.LogError("ParallaxCompositor: " + e.Status + ": " + e.Message);
                return false;
            }
        }

        // Warnings only: a failed call's error arrives as its ParallaxException, logged by Compose.
        static void Forward(PlxLogLevel level, string message)
        {
            if (level == PlxLogLevel.Warn)
                Debug.LogWarning("Parallax: " + message);
        }

        /// <summary>Unity's bottom-up Color32 rows as a top-down RGBA8 buffer.</summary>
        static byte[] TopDownRgba(Color32[] pixels, int w, int h)
        {
            byte[] rgba = new byte[w * h * 4];
            for (int y = 0; y < h; y++)
            {
                int src = (h - 1 - y) * w, dst = y * w * 4;
                for (int x = 0; x < w; x++, dst += 4)
                {
                    Color32 c = pixels[src + x];
                    rgba[dst] = c.r;
                    rgba[dst + 1] = c.g;
                    rgba[dst + 2] = c.b;
                    rgba[dst + 3] = c.a;
                }
            }
            return rgba;
        }

        /// <summary>A top-down RGBA8 buffer as Unity's bottom-up Color32 rows.</summary>
        static Color32[] BottomUpColors(byte[] rgba, int w, int h)
        {
            Color32[] pixels = new Color32[w * h];
            for (int y = 0; y < h; y++)
            {
                int src = y * w * 4, dst = (h - 1 - y) * w;
                for (int x = 0; x < w; x++, src += 4)
                    pixels[dst + x] = new Color32(rgba[src], rgba[src + 1], rgba[src + 2], rgba[src + 3]);
            }
            return pixels;
        }
    }
}
