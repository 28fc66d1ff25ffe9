// The VS Code client: starts `pccl lsp` (setting pccl.server.command) for
// .pccl files and their world files.
const vscode = require("vscode");
const { LanguageClient } = require("vscode-languageclient/node");

let client;

function activate(context) {
  const [command, ...args] = vscode.workspace
    .getConfiguration("pccl")
    .get("server.command", ["pccl", "lsp"]);
  client = new LanguageClient(
    "pccl",
    "PCCL language server",
    { command, args },
    {
      documentSelector: [
        { scheme: "file", language: "pccl" },
        { scheme: "file", pattern: "**/*.toml" },
      ],
    }
  );
  context.subscriptions.push(client);
  return client.start();
}

function deactivate() {
  return client ? client.stop() : undefined;
}

module.exports = { activate, deactivate };
