//! `hyrt view --script FILE`: what a user would do, at given frames, for unattended runs.

use std::path::Path;

use super::stages::View;

/// The script language, for `--help-script`.
pub const HELP: &str = "\
hyrt view --script FILE: one action per line, `FRAME ACTION [ARGS]`, applied before frame
FRAME (0 is the first) renders; `#` starts a comment. Actions:
  view KEY          show the view of key KEY (1-9, 0, -, =; as in the window)
  orbit DX DY       turn the camera by DX, DY radians (as a mouse drag)
  zoom F            move toward the target by F of the distance (negative: away)
  move F R U        move the eye and target F forward, R right, U up (world units)
  mode              switch between orbit and fly
  reset             the starting camera
  scene-camera      the scene's own camera
  click X Y         toggle the object at pixel (X, Y) between ray traced and rasterized
  weight W          set the composition weight (0..1)
  exposure S        set the display's exposure, in stops
  tone-map          the next tone-mapping operator (none, khronos-pbr-neutral, aces)
  play              play or pause the animation (it loops)
  time T            pose the animation at T seconds
  light             the next light's shadow mask
  overlay           show or hide the overlay
  screenshot        write the current view to hyrt-view-NNNN.png (no overlay)
  screenshot-overlay  the same with the overlay
  quit              close the viewer
Example: `0 click 320 200` then `2 view 9` then `3 screenshot`.";

/// One thing a key, the mouse or a script line does.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Action {
    View(View),
    ToggleMode,
    Reset,
    SceneCamera,
    PlayPause,
    /// Pause and move the animation by this many seconds.
    StepTime(f32),
    /// Pose the animation at this time in seconds.
    SetTime(f32),
    AddWeight(f32),
    SetWeight(f32),
    /// Change the display's exposure by this many stops.
    AddExposure(f32),
    /// Set the display's exposure, in stops.
    SetExposure(f32),
    /// The next tone-mapping operator.
    NextToneMap,
    NextLight,
    ToggleOverlay,
    Screenshot {
        overlay: bool,
    },
    Orbit(f32, f32),
    Zoom(f32),
    Move(f32, f32, f32),
    Click(u32, u32),
    Quit,
}

/// Actions by frame.
#[derive(Clone, Debug, Default)]
pub struct Script {
    steps: Vec<(u32, Action)>,
}

impl Script {
    pub fn load(path: &Path) -> Result<Script, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        Script::parse(&text).map_err(|e| format!("{}: {e}", path.display()))
    }

    pub fn parse(text: &str) -> Result<Script, String> {
        let mut steps = Vec::new();
        for (n, line) in text.lines().enumerate() {
            let line = line.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let bad = |why: &str| format!("line {}: {why}: '{line}' (hyrt view --help-script)", n + 1);
            let words: Vec<&str> = line.split_whitespace().collect();
            let frame: u32 = words[0].parse().map_err(|_| bad("expected a frame number first"))?;
            let f = |i: usize| -> Result<f32, String> {
                let w = words.get(i).ok_or_else(|| bad("missing a number"))?;
                w.parse::<f32>().ok().filter(|x| x.is_finite()).ok_or_else(|| bad("bad number"))
            };
            let u = |i: usize| -> Result<u32, String> {
                words.get(i).and_then(|w| w.parse().ok()).ok_or_else(|| bad("expected a pixel coordinate"))
            };
            let action = match words.get(1).copied().unwrap_or("") {
                "view" => {
                    let key = words.get(2).ok_or_else(|| bad("missing the view's key"))?;
                    let i = View::KEYS.iter().position(|k| k == key).ok_or_else(|| bad("no view has that key"))?;
                    Action::View(View::ALL[i])
                }
                "orbit" => Action::Orbit(f(2)?, f(3)?),
                "zoom" => Action::Zoom(f(2)?),
                "move" => Action::Move(f(2)?, f(3)?, f(4)?),
                "mode" => Action::ToggleMode,
                "reset" => Action::Reset,
                "scene-camera" => Action::SceneCamera,
                "click" => Action::Click(u(2)?, u(3)?),
                "weight" => Action::SetWeight(f(2)?.clamp(0.0, 1.0)),
                "exposure" => Action::SetExposure(f(2)?),
                "tone-map" => Action::NextToneMap,
                "play" => Action::PlayPause,
                "time" => Action::SetTime(f(2)?),
                "light" => Action::NextLight,
                "overlay" => Action::ToggleOverlay,
                "screenshot" => Action::Screenshot { overlay: false },
                "screenshot-overlay" => Action::Screenshot { overlay: true },
                "quit" => Action::Quit,
                _ => return Err(bad("unknown action")),
            };
            steps.push((frame, action));
        }
        Ok(Script { steps })
    }

    /// The actions of frame `frame`, in the file's order.
    pub fn at(&self, frame: u32) -> Vec<Action> {
        self.steps.iter().filter(|(f, _)| *f == frame).map(|(_, a)| *a).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_actions_and_refuses_nonsense() {
        let s =
            Script::parse("# a comment\n0 click 3 4\n2 view 9 # flag\n2 orbit 0.1 -0.2\n4 time 1.5\n5 quit\n").unwrap();
        assert_eq!(s.at(4), vec![Action::SetTime(1.5)]);
        assert_eq!(s.at(0), vec![Action::Click(3, 4)]);
        assert_eq!(s.at(2), vec![Action::View(View::RayTracedFlag), Action::Orbit(0.1, -0.2)]);
        assert!(s.at(1).is_empty());
        assert!(Script::parse("x view 1").is_err());
        assert!(Script::parse("0 fly").is_err());
        assert!(Script::parse("0 view 11").is_err());
        assert!(Script::parse("0 zoom nan").is_err());
    }
}
