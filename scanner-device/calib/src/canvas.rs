//! The small drawing kit the overlays and the printable sheets use: lines of a chosen width and
//! text without a font file ([`Canvas`]).

use image::{GrayImage, Rgb, RgbImage};

/// An RGB picture with simple drawing.
pub struct Canvas {
    /// The picture.
    pub image: RgbImage,
}

impl Canvas {
    /// A canvas from a gray image.
    pub fn from_gray(img: &GrayImage) -> Canvas {
        let image = RgbImage::from_fn(img.width(), img.height(), |x, y| {
            let v = img.get_pixel(x, y)[0];
            Rgb([v, v, v])
        });
        Canvas { image }
    }

    /// A blank canvas.
    pub fn blank(width: u32, height: u32, c: Rgb<u8>) -> Canvas {
        Canvas {
            image: RgbImage::from_pixel(width, height, c),
        }
    }

    /// Sets a pixel if inside.
    pub fn dot(&mut self, x: i64, y: i64, c: Rgb<u8>) {
        if x >= 0 && y >= 0 && (x as u32) < self.image.width() && (y as u32) < self.image.height() {
            self.image.put_pixel(x as u32, y as u32, c);
        }
    }

    /// A line `width` pixels thick.
    pub fn line(&mut self, a: (f64, f64), b: (f64, f64), width: f64, c: Rgb<u8>) {
        let len = ((b.0 - a.0).powi(2) + (b.1 - a.1).powi(2)).sqrt();
        if !len.is_finite() || len > 1e5 {
            return;
        }
        let steps = (len * 2.0).ceil().max(1.0) as usize;
        let r = (width / 2.0).max(0.5);
        for s in 0..=steps {
            let t = s as f64 / steps as f64;
            let (x, y) = (a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1));
            self.disc((x, y), r, c);
        }
    }

    /// A filled disc.
    pub fn disc(&mut self, at: (f64, f64), r: f64, c: Rgb<u8>) {
        let ri = r.ceil() as i64;
        for dy in -ri..=ri {
            for dx in -ri..=ri {
                let (x, y) = (at.0.round() as i64 + dx, at.1.round() as i64 + dy);
                if ((x as f64 - at.0).powi(2) + (y as f64 - at.1).powi(2)) <= r * r + 0.25 {
                    self.dot(x, y, c);
                }
            }
        }
    }

    /// A circle outline.
    pub fn circle(&mut self, at: (f64, f64), r: f64, width: f64, c: Rgb<u8>) {
        let n = ((r * 8.0).ceil() as usize).clamp(16, 2000);
        for i in 0..n {
            let (a0, a1) = (
                i as f64 / n as f64 * std::f64::consts::TAU,
                (i + 1) as f64 / n as f64 * std::f64::consts::TAU,
            );
            self.line(
                (at.0 + r * a0.cos(), at.1 + r * a0.sin()),
                (at.0 + r * a1.cos(), at.1 + r * a1.sin()),
                width,
                c,
            );
        }
    }

    /// An × of half size `r`.
    pub fn cross(&mut self, at: (f64, f64), r: f64, width: f64, c: Rgb<u8>) {
        self.line((at.0 - r, at.1 - r), (at.0 + r, at.1 + r), width, c);
        self.line((at.0 - r, at.1 + r), (at.0 + r, at.1 - r), width, c);
    }

    /// A filled rectangle.
    pub fn rect(&mut self, x0: f64, y0: f64, x1: f64, y1: f64, c: Rgb<u8>) {
        for y in y0.round() as i64..y1.round() as i64 {
            for x in x0.round() as i64..x1.round() as i64 {
                self.dot(x, y, c);
            }
        }
    }

    /// Text in the 8×8 bitmap font, `scale` pixels per font pixel, top-left at `(x, y)`;
    /// returns the width drawn.
    pub fn text(&mut self, x: f64, y: f64, s: &str, scale: u32, c: Rgb<u8>) -> f64 {
        use font8x8::UnicodeFonts;
        let sc = i64::from(scale.max(1));
        let mut cx = x.round() as i64;
        for ch in s.chars() {
            let glyph = font8x8::BASIC_FONTS
                .get(ch)
                .or_else(|| font8x8::LATIN_FONTS.get(ch))
                .unwrap_or([0; 8]);
            for (row, bits) in glyph.iter().enumerate() {
                for col in 0..8 {
                    if bits >> col & 1 == 1 {
                        for dy in 0..sc {
                            for dx in 0..sc {
                                self.dot(
                                    cx + col * sc + dx,
                                    y.round() as i64 + row as i64 * sc + dy,
                                    c,
                                );
                            }
                        }
                    }
                }
            }
            cx += 8 * sc;
        }
        (cx as f64) - x
    }

    /// Lines of text on a dark box at the top left.
    pub fn legend(&mut self, lines: &[(String, Rgb<u8>)], scale: u32) {
        // Long lines (an error message) wrap at spaces to stay inside the image.
        let per_line =
            ((self.image.width() as usize).saturating_sub(12) / (8 * scale as usize)).max(16);
        let wrapped: Vec<(String, Rgb<u8>)> = lines
            .iter()
            .flat_map(|(l, c)| wrap(l, per_line).into_iter().map(move |w| (w, *c)))
            .collect();
        let lines = &wrapped[..];
        let h = 10.0 * f64::from(scale);
        let w = lines
            .iter()
            .map(|(l, _)| l.chars().count())
            .max()
            .unwrap_or(0) as f64
            * 8.0
            * f64::from(scale);
        self.rect(
            0.0,
            0.0,
            w + 12.0,
            h * lines.len() as f64 + 8.0,
            Rgb([0, 0, 0]),
        );
        for (i, (l, c)) in lines.iter().enumerate() {
            self.text(6.0, 4.0 + h * i as f64, l, scale, *c);
        }
    }
}

/// Splits `s` at spaces into lines of at most `width` characters (a longer word is cut).
fn wrap(s: &str, width: usize) -> Vec<String> {
    let mut out = Vec::new();
    let mut line = String::new();
    for word in s.split(' ') {
        let mut word: Vec<char> = word.chars().collect();
        while word.len() > width {
            if !line.is_empty() {
                out.push(std::mem::take(&mut line));
            }
            out.push(word.drain(..width).collect());
        }
        let word: String = word.into_iter().collect();
        if !line.is_empty() && line.chars().count() + 1 + word.chars().count() > width {
            out.push(std::mem::take(&mut line));
        }
        if !line.is_empty() {
            line.push(' ');
        }
        line.push_str(&word);
    }
    if !line.is_empty() || out.is_empty() {
        out.push(line);
    }
    out
}
