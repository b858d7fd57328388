/* viewer/lu_font.h — a tiny built-in 5x7 bitmap font for the viewer's
 * on-screen overlay (fps, method, backend, samples), drawn into an 8-bit RGB
 * buffer on the CPU so the overlay needs no font files and no GL text path.
 * Covers digits, A-Z (lower case is drawn as upper case), space and
 * . , : ; / = - + ( ) [ ] % _ < > ' ? ! #, and a small x between digits
 * ("640x480"); other characters draw as '?'. */
#ifndef LU_VIEWER_FONT_H
#define LU_VIEWER_FONT_H

#include <stdint.h>

#define LU_FONT_W 5
#define LU_FONT_H 7

/* Width in pixels of text drawn at `scale` (one column of spacing per glyph). */
int lu_font_text_width(const char *text, int scale);

/* Draws text with its top-left corner at (x, y) into rgb (width x height,
 * 3 bytes per pixel, top row first), clipped to the buffer. */
void lu_font_draw(uint8_t *rgb, int width, int height, int x, int y, const char *text, int scale,
                  const uint8_t color[3]);

/* Darkens the rectangle [x, x+w) x [y, y+h) to a quarter of its brightness
 * (a backdrop that keeps overlay text legible over bright images). */
void lu_font_backdrop(uint8_t *rgb, int width, int height, int x, int y, int w, int h);

/* The 7 row bitmaps of character c (bit 4 = leftmost column). */
const uint8_t *lu_font_glyph(char c);

#endif
