#include "generators/pipeline/progress.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <ostream>

namespace chromasim::generators {

namespace {

double seconds(std::chrono::steady_clock::duration d) {
    return std::chrono::duration<double>(d).count();
}

std::string duration_text(double s) {
    char buf[64];
    if (!std::isfinite(s)) return "?";
    if (s < 60.0)
        std::snprintf(buf, sizeof buf, "%.0f s", s);
    else if (s < 3600.0)
        std::snprintf(buf, sizeof buf, "%d min %02d s", int(s / 60), int(s) % 60);
    else
        std::snprintf(buf, sizeof buf, "%d h %02d min", int(s / 3600), int(s / 60) % 60);
    return buf;
}

} // namespace

Progress::Progress(std::ostream& out, std::size_t total_frames, bool terminal, bool quiet,
                   double interval_s)
    : m_out(out), m_total(total_frames), m_terminal(terminal), m_quiet(quiet),
      m_interval_s(interval_s), m_start(std::chrono::steady_clock::now()), m_last(m_start) {}

std::string Progress::describe(std::size_t done, std::size_t total, double elapsed_s, bool bar) {
    const double rate = elapsed_s > 0.0 ? double(done) / elapsed_s : 0.0;
    const double left = rate > 0.0 ? double(total - std::min(done, total)) / rate
                                   : std::numeric_limits<double>::infinity();
    std::string text = "  ";
    if (bar) {
        constexpr int kWidth = 24;
        const int filled =
            std::clamp(total > 0 ? int(kWidth * double(done) / double(total)) : kWidth, 0, kWidth);
        text.push_back('[');
        text.append(std::size_t(filled), '#');
        text.append(std::size_t(kWidth - filled), '.');
        text.append("]  ");
    } else {
        text.append("progress: ");
    }
    char buf[160];
    std::snprintf(buf, sizeof buf, "%zu/%zu frames  %.2f frames/s  ETA %s", done, total, rate,
                  done >= total ? "0 s" : duration_text(left).c_str());
    return text + buf;
}

void Progress::print(bool force) {
    if (m_quiet) return;
    const auto now = std::chrono::steady_clock::now();
    const double since = seconds(now - m_last);
    if (!force && m_printed && since < (m_terminal ? 0.1 : m_interval_s)) return;
    m_printed = true;
    m_last = now;
    const std::string text = describe(m_done, m_total, seconds(now - m_start), m_terminal);
    if (m_terminal) {
        m_out << '\r' << text << "\033[K" << std::flush; // \033[K: erase to the end of the line
        m_drawn = true;
    } else {
        m_out << text << '\n' << std::flush;
    }
}

void Progress::advance(std::size_t frames) {
    m_done += frames;
    print(false);
}

void Progress::clear() {
    if (m_terminal && m_drawn && !m_quiet) m_out << "\r\033[K" << std::flush;
    m_drawn = false;
}

void Progress::finish() {
    print(true);
    if (m_terminal && !m_quiet) m_out << '\n' << std::flush;
    m_drawn = false;
}

} // namespace chromasim::generators
