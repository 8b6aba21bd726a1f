#include "app/web_ui.h"

#include <cstdio>
#include <mutex>
#include <stdexcept>
#include <utility>

#include "common/check.h"

namespace msmcal::app {

void AddWebUiOptions(CLI::App* command, WebUiArgs* args) {
  CLI::Option* ui = command->add_option(
      "--ui", args->ui,
      "web[:PORT]: the live view in a browser (camera image with the quality "
      "gate's overlay, instructions, Ready / Repeat / Abort, live figures, rig "
      "state) at http://127.0.0.1:PORT/ (default " +
          std::to_string(live_view::kDefaultLivePort) + "; 0: any free port; the URL is printed)");
  command
      ->add_option("--ui-bind", args->bind,
                   "Serve the live view on this address instead of 127.0.0.1 (e.g. 0.0.0.0 "
                   "for the lab network); the printed URL then carries a random access token")
      ->needs(ui);  // alone it would be ignored
}

// The view, once Start()ed, shared with the observers handed to the orchestrator (which may be
// made before it exists).
struct WebUi::Shared {
  std::mutex mu;
  dataset::Recording plan;
  std::unique_ptr<live_view::LiveView> view;
  std::unique_ptr<live_view::LiveServer> server;
  live_view::LiveView* View() {
    std::lock_guard<std::mutex> lock(mu);
    return view.get();
  }
};

WebUi::WebUi(const WebUiArgs& args) : args_(args), shared_(std::make_shared<Shared>()) {
  server_options_.port = live_view::ParseUiWebOption(args.ui);
  if (!args.bind.empty()) {
    server_options_.bind_address = args.bind;
    server_options_.allow_remote = true;
  }
  if (std::string e = server_options_.Validate(); !e.empty())
    throw std::invalid_argument("--ui-bind " + args.bind + ": " + e);
}

WebUi::~WebUi() {
  // The server first (its threads read the view), then the view.
  if (shared_->server) shared_->server->Stop();
}

void WebUi::Start(const dataset::Recording& plan, const std::filesystem::path& session_dir,
                  const orchestrator::GateOptions& gate) {
  MSMCAL_CHECK(!shared_->View()) << "WebUi::Start called twice";
  live_view::LiveViewOptions vo;
  vo.disk_path = session_dir;
  vo.gate = gate;
  std::lock_guard<std::mutex> lock(shared_->mu);
  shared_->plan = plan;
  shared_->view = std::make_unique<live_view::LiveView>(shared_->plan, vo);
  shared_->server = live_view::LiveServer::Start(*shared_->view, server_options_);
  std::printf(
      "live view: open %s in a browser on this PC%s\n", shared_->server->url().c_str(),
      server_options_.allow_remote ? " (or from the lab network; keep the token private)" : "");
  std::fflush(stdout);
}

std::string WebUi::url() const {
  std::lock_guard<std::mutex> lock(shared_->mu);
  return shared_->server ? shared_->server->url() : std::string();
}

std::unique_ptr<orchestrator::RigOperator> WebUi::MakeOperator(
    live_view::WebOperatorOptions options, orchestrator::RigOperator* inner) {
  live_view::LiveView* view = shared_->View();
  MSMCAL_CHECK(view) << "WebUi::MakeOperator before Start";
  if (!options.echo)
    options.echo = [](const std::string& text) {
      std::fputs(text.c_str(), stdout);
      std::fflush(stdout);
    };
  std::lock_guard<std::mutex> lock(shared_->mu);
  return std::make_unique<live_view::WebOperator>(shared_->plan, *view, std::move(options), inner);
}

void WebUi::Observe(orchestrator::OrchestratorOptions& o) {
  auto shared = shared_;
  o.on_frame = [shared, before = std::move(o.on_frame)](const orchestrator::FrameReport& r) {
    if (before) before(r);
    if (auto* v = shared->View()) v->MakeFrameObserver()(r);
  };
  o.on_live_frame = [shared,
                     before = std::move(o.on_live_frame)](const orchestrator::LiveFrame& f) {
    if (before) before(f);
    if (auto* v = shared->View()) v->MakeLiveFrameObserver()(f);
  };
  o.on_rig_status = [shared,
                     before = std::move(o.on_rig_status)](const orchestrator::RigStatus& s) {
    if (before) before(s);
    if (auto* v = shared->View()) v->MakeRigStatusObserver()(s);
  };
}

void WebUi::AddLogLine(const std::string& line) {
  if (auto* v = shared_->View()) v->AddLogLine(line);
}

void WebUi::Finished(bool done, const std::string& message) {
  if (auto* v = shared_->View())
    v->SetState(done ? live_view::SessionState::kDone : live_view::SessionState::kAborted, message);
}

}  // namespace msmcal::app
