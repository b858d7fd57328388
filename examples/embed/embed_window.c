/* Embedding lucent in a program with its own window: a GLFW window whose
 * OpenGL 4.5 context the GPU methods work in (gl_caller_context), frames
 * rendered straight into a texture of that context and shown with a
 * framebuffer blit, with no copy through the CPU. Renders `frames` frames
 * with the camera turning, then reads the last frame's texture back and
 * saves it, so a test can compare it with `lucent render`.
 *
 *   embed_window SCENE.json OUT.pfm [METHOD [WxH [frames]]]
 *
 * lucent changes the program and the buffer, texture and image bindings it
 * uses in the context; this program sets its own state again each frame. */
#include <lucent/lucent.h>

#include <epoxy/gl.h>
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

int main(int argc, char **argv) {
    if (argc < 3) {
        fprintf(stderr, "usage: %s SCENE.json OUT.pfm [METHOD [WxH [frames]]]\n", argv[0]);
        return 2;
    }
    lu_error err = {0};
    lu_scene scene = {0};
    if (lu_scene_load(argv[1], &scene, &err) != LU_OK) {
        fprintf(stderr, "embed_window: %s\n", err.message);
        return 1;
    }
    int w = scene.camera.width, h = scene.camera.height, frames = argc > 5 ? atoi(argv[5]) : 3;
    if (argc > 4 && sscanf(argv[4], "%dx%d", &w, &h) != 2) w = 0;
    if (w < 1 || h < 1 || frames < 1) {
        fprintf(stderr, "embed_window: bad size or frame count\n");
        return 2;
    }
    scene.camera.width = w;
    scene.camera.height = h;
    if (!glfwInit()) {
        fprintf(stderr, "embed_window: no display\n");
        return 1;
    }
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 5);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_CONTEXT_CREATION_API, GLFW_EGL_CONTEXT_API);
    GLFWwindow *win = glfwCreateWindow(w, h, "lucent embed", NULL, NULL);
    if (!win) {
        glfwWindowHint(GLFW_CONTEXT_CREATION_API, GLFW_NATIVE_CONTEXT_API);
        win = glfwCreateWindow(w, h, "lucent embed", NULL, NULL);
    }
    if (!win) {
        fprintf(stderr, "embed_window: no OpenGL 4.5 window\n");
        return 1;
    }
    glfwMakeContextCurrent(win);

    /* The frame's texture and a framebuffer to blit it from. */
    GLuint tex = 0, fbo = 0;
    glCreateTextures(GL_TEXTURE_2D, 1, &tex);
    glTextureStorage2D(tex, 1, GL_RGBA32F, w, h);
    glCreateFramebuffers(1, &fbo);
    glNamedFramebufferTexture(fbo, GL_COLOR_ATTACHMENT0, tex, 0);

    lu_renderer_desc desc = {.method = argc > 3 ? argv[3] : "raymarch", .backend = LU_BACKEND_GPU,
                             .gl_caller_context = true};
    lu_renderer *r = NULL;
    int rc = 1;
    lu_vec3 d0 = lu_v3_sub(scene.camera.position, scene.camera.look_at);
    if (lu_renderer_make(&desc, &scene, &r, &err) != LU_OK) goto done;
    for (int f = 0; f < frames && !glfwWindowShouldClose(win); f++) {
        /* the camera turns a little each frame; the last frame is the scene's own view */
        float a = 0.05f * (float)(frames - 1 - f), c = cosf(a), s = sinf(a);
        scene.camera.position = lu_v3_add(scene.camera.look_at, lu_v3(c * d0.x + s * d0.z, d0.y, -s * d0.x + c * d0.z));
        if (lu_renderer_render_texture(r, &scene, tex, &err) != LU_OK) goto done;
        int fw, fh;
        glfwGetFramebufferSize(win, &fw, &fh);
        glBlitNamedFramebuffer(fbo, 0, 0, 0, w, h, 0, 0, fw, fh, GL_COLOR_BUFFER_BIT, GL_LINEAR);
        glfwSwapBuffers(win);
        glfwPollEvents();
    }
    lu_renderer_stats st;
    if (lu_renderer_get_stats(r, &st, &err) != LU_OK) goto done;
    printf("%d frames of %s on %s into the window's texture%s\n", frames, st.method, lu_backend_name(st.backend),
           st.texture_direct ? " (texture_direct: no copy through the CPU)" : " (through CPU memory)");

    /* The last frame back from the texture (rows bottom to top) for comparison. */
    lu_image out = {0};
    float *px = malloc((size_t)w * h * 4 * sizeof *px);
    if (!px || lu_image_create(&out, w, h, &err) != LU_OK) {
        free(px);
        goto done;
    }
    glGetTextureImage(tex, 0, GL_RGBA, GL_FLOAT, (GLsizei)((size_t)w * h * 4 * sizeof *px), px);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            for (int k = 0; k < 3; k++) out.rgb[((size_t)y * w + x) * 3 + k] = px[((size_t)(h - 1 - y) * w + x) * 4 + k];
    free(px);
    if (lu_image_save(&out, argv[2], NULL, &err) == LU_OK) rc = 0;
    lu_image_destroy(&out);
done:
    if (rc != 0) fprintf(stderr, "embed_window: %s\n", err.message);
    lu_renderer_destroy(r);   /* in the window's context, where its objects live */
    glDeleteFramebuffers(1, &fbo);
    glDeleteTextures(1, &tex);
    glfwDestroyWindow(win);
    lu_scene_destroy(&scene);
    return rc;
}
