#pragma once
/// Progress of a generation on its log: on a terminal, one line redrawn in place (a bar, frames
/// done of the total, frames per second, time left); otherwise a plain line every
/// `interval_s` seconds and at the end; nothing when quiet. No Debian package offers a C++
/// progress bar (indicators and the like are not packaged), so this is the project's own.
#include <chrono>
#include <cstddef>
#include <iosfwd>
#include <string>

namespace chromasim::generators {

class Progress {
public:
    Progress(std::ostream& out, std::size_t total_frames, bool terminal, bool quiet,
             double interval_s = 10.0);

    /// `frames` more frames are done; redraws (terminal, at most every 0.1 s) or prints a line
    /// when `interval_s` has passed since the last (the first update at once).
    void advance(std::size_t frames = 1);
    /// Erases the terminal line so that a log line can follow (a no-op otherwise).
    void clear();
    /// The last state, then a newline on a terminal.
    void finish();

    /// "  [######....]  120/680 frames  3.2 frames/s  ETA 2 min 55 s" (without the bar when
    /// `bar` is false). Exposed for tests.
    static std::string describe(std::size_t done, std::size_t total, double elapsed_s, bool bar);

private:
    void print(bool force);

    std::ostream& m_out;
    std::size_t m_total, m_done = 0;
    bool m_terminal, m_quiet;
    double m_interval_s;
    std::chrono::steady_clock::time_point m_start, m_last;
    bool m_drawn = false;   ///< the terminal line shows the bar
    bool m_printed = false; ///< the first update is shown at once
};

} // namespace chromasim::generators
